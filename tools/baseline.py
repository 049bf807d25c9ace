"""What the baseline recorders (tools/scenes_baseline.py, tools/simd_baseline.py) share: messages
named by the script, git and commands that stop the script on failure, and the record written
whole or not at all."""
import json
import os
import subprocess
import sys


class Recorder:
    def __init__(self, name):
        self.name = name

    def fail(self, message):
        print(f"{self.name}: {message}", file=sys.stderr)
        sys.exit(1)

    def git(self, repo, *args):
        result = subprocess.run(["git", "-C", repo, *args], capture_output=True, text=True)
        if result.returncode != 0:
            self.fail(f"git {' '.join(args)}: {result.stderr.strip()}")
        return result.stdout.strip()

    def run(self, command, **kwargs):
        print(f"{self.name}: " + " ".join(command), file=sys.stderr)
        if subprocess.run(command, **kwargs).returncode != 0:
            self.fail(f"failed: {' '.join(command)}")

    def write(self, record, out):
        os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
        tmp = out + ".tmp"
        with open(tmp, "w") as f:
            json.dump(record, f, indent=1)
            f.write("\n")
        os.replace(tmp, out)
        print(f"{self.name}: wrote {out}")
