"""What the baseline recorders (tools/scenes_baseline.py, tools/simd_baseline.py) share: messages
named by the script, git and commands that stop the script on failure, a wait for a quiet machine,
and the record written whole or not at all."""
import json
import os
import subprocess
import sys
import time


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

    def settle(self):
        """Waits (at most DRAPE_BENCH_SETTLE seconds, 300 by default) for a 1-minute load average
        below 0.5, as tools/bench.sh does before each run: the build just finished would otherwise
        share the cores with the first repetitions. Returns the load averages the run starts at."""
        limit = int(os.environ.get("DRAPE_BENCH_SETTLE", "300"))
        waited = 0
        while os.getloadavg()[0] >= 0.5 and waited < limit:
            time.sleep(10)
            waited += 10
        load = list(os.getloadavg())
        print(f"{self.name}: starting at load {load[0]:.2f} (waited {waited} s)", file=sys.stderr)
        return load

    def write(self, record, out):
        os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
        tmp = out + ".tmp"
        with open(tmp, "w") as f:
            json.dump(record, f, indent=1)
            f.write("\n")
        os.replace(tmp, out)
        print(f"{self.name}: wrote {out}")
