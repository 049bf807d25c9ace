"""What the baseline recorders (tools/scenes_baseline.py, tools/simd_baseline.py) and the pairing
scripts (tools/portable_pair.py, tools/floor_pair.py) share: messages named by the script, git and
commands that stop the script on failure, a wait for a quiet machine, binaries (or benchmarks of
one binary) measured in alternating rounds, and the record written whole or not at all."""
import json
import os
import subprocess
import sys
import tempfile
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

    def alternate(self, sides, rounds):
        """Runs each side's drape_bench (sides: name -> (command, environment)) once per round, one
        repetition each, the sides' order turning every round, and returns each side's runs of all
        rounds as one Google Benchmark JSON (tools/bench_report.py shows the fastest of a
        benchmark's runs and divides round by round). A virtual machine's slow spell lasts minutes and slows whatever runs in
        it: two runs minutes apart, one of each binary, can differ by 30 % with no change between
        them, while rounds of the two binaries side by side see the same spells."""
        merged = {name: None for name in sides}
        names = list(sides)
        with tempfile.TemporaryDirectory(prefix="drape-rounds-") as scratch:
            for round_ in range(rounds):
                for name in names[round_ % len(names):] + names[:round_ % len(names)]:
                    command, env = sides[name]
                    raw = os.path.join(scratch, f"{name}-{round_}.json")
                    self.run([*command, "--benchmark_repetitions=1", f"--benchmark_out={raw}",
                              "--benchmark_out_format=json"], env={**os.environ, **env}, stdout=subprocess.DEVNULL)
                    with open(raw) as f:
                        data = json.load(f)
                    if merged[name] is None:
                        merged[name] = data
                    else:
                        merged[name]["benchmarks"] += data.get("benchmarks", [])
        return merged

    def check_sides(self, rounds, *benches):
        """Stops the script unless rounds ≥ 1 and every bench is an executable file."""
        if rounds < 1:
            self.fail(f"--rounds must be at least 1, not {rounds}")
        for bench in benches:
            if not os.access(bench, os.X_OK):
                self.fail(f"{bench}: not an executable drape_bench")

    def pair(self, sides, rounds, what):
        """A quiet machine, then `alternate`; stops the script if a side produced no results.
        Returns each side's runs and how they were measured (for the record's "paired" field)."""
        load_before = self.settle()
        measured = self.alternate(sides, rounds)
        for name, data in measured.items():
            if not data.get("benchmarks"):
                self.fail(f"{name}: the run produced no results (does the filter match?)")
        return measured, {"rounds": rounds, "load_avg_before": load_before, "load_avg_after": list(os.getloadavg()),
                          "what": what}

    def write(self, record, out):
        os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
        tmp = out + ".tmp"
        with open(tmp, "w") as f:
            json.dump(record, f, indent=1)
            f.write("\n")
        os.replace(tmp, out)
        print(f"{self.name}: wrote {out}")
