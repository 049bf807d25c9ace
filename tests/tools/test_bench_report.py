"""The arithmetic tools/bench_report.py turns benchmark JSON into verdicts with, on inputs whose
answers are worked out by hand here (no drape build needed)."""
import math
import os
import sys
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tools"))
import bench_report  # noqa: E402


def single(name, seconds, cpu_seconds=None, points=1024, substeps=1):
    """One repetition of a benchmark as Google Benchmark writes it, times in ms."""
    return {"name": name, "run_name": name, "run_type": "iteration", "time_unit": "ms",
            "real_time": seconds * 1e3, "cpu_time": (cpu_seconds if cpu_seconds is not None else seconds) * 1e3,
            "points": points, "substeps": substeps}


def aggregate(name, kind, seconds):
    entry = single(name, seconds)
    entry.update(run_type="aggregate", aggregate_name=kind)
    return entry


def rounds_run(name, seconds, cpu_seconds=None, **kw):
    """A run of alternating rounds: one single repetition per round, in order."""
    cpus = cpu_seconds or seconds
    data = {"benchmarks": [single(name, s, c, **kw) for s, c in zip(seconds, cpus)]}
    return bench_report.runs_of(data)[name]


class TermCost(unittest.TestCase):
    def test_the_stage_is_in_contact_less_apart_and_the_target_leaves_the_rest(self):
        # 9 ms in contact, 0.6 ms apart: the contacts took 8.4 ms; at most 4× apart is 2.4 ms a
        # substep, of which the sheets take their 0.6 ms and the contacts may take 1.8 ms
        stage, budget = bench_report.term_cost(0.009, 0.0006, 4.0)
        self.assertAlmostEqual(stage, 0.0084, places=15)
        self.assertAlmostEqual(budget, 0.0018, places=15)

    def test_a_price_in_per_cent_leaves_that_share_of_the_bare_step(self):
        # a floor: 1.1 ms on it, 0.5 ms bare; it took 0.6 ms, and at most +40 % leaves it 0.2 ms
        cost, budget = bench_report.term_cost(0.0011, 0.0005, 1.4)
        self.assertAlmostEqual(cost, 0.0006, places=15)
        self.assertAlmostEqual(budget, 0.0002, places=15)


class TimesFaster(unittest.TestCase):
    def test_median_of_the_ratio_within_each_round(self):
        # rounds (slow, fast): (10, 5), (12, 4), (30, 10): ratios 2, 3, 3, median 3. The fastest
        # of each side would give 10 ÷ 4 = 2.5, a ratio no round saw.
        slow = rounds_run("BM_A", [0.010, 0.012, 0.030])
        fast = rounds_run("BM_A", [0.005, 0.004, 0.010])
        self.assertAlmostEqual(bench_report.times_faster(slow, fast), 3.0, places=12)

    def test_one_lucky_round_does_not_decide(self):
        # the fast side's second round is 4× quicker than its others; within rounds the ratios
        # are 1, 4 and 1, so the verdict is 1
        slow = rounds_run("BM_A", [0.010, 0.010, 0.010])
        fast = rounds_run("BM_A", [0.010, 0.0025, 0.010])
        self.assertAlmostEqual(bench_report.times_faster(slow, fast), 1.0, places=12)

    def test_cpu_time_rounds_are_paired_apart_from_wall_time(self):
        # a /real_time benchmark: wall time stretched by a busy machine in two of the slow
        # side's rounds, its CPU time not
        slow = rounds_run("BM_A/real_time", [0.040, 0.040, 0.010], cpu_seconds=[0.010, 0.010, 0.010])
        fast = rounds_run("BM_A/real_time", [0.005, 0.005, 0.005])
        self.assertAlmostEqual(bench_report.times_faster(slow, fast), 8.0, places=12)  # median of 8, 8, 2
        self.assertAlmostEqual(bench_report.times_faster(slow, fast, cpu=True), 2.0, places=12)

    def test_scaled_by_the_work_of_an_iteration(self):
        # the same time for twice the points and three times the substeps: 6× the point-steps
        slow = rounds_run("BM_A", [0.010, 0.010], points=1000, substeps=1)
        fast = rounds_run("BM_A", [0.010, 0.010], points=2000, substeps=3)
        self.assertAlmostEqual(bench_report.times_faster(slow, fast), 6.0, places=12)

    def test_a_run_without_points_is_not_scaled_by_the_others(self):
        # only one side counts its points: the same time is the same speed, not 1024× apart
        slow = rounds_run("BM_A", [0.010, 0.010], points=None)
        fast = rounds_run("BM_A", [0.010, 0.010])
        self.assertAlmostEqual(bench_report.times_faster(slow, fast), 1.0, places=12)

    def test_unequal_rounds_fall_back_to_the_figures(self):
        # 3 rounds against 2: not paired, so the fastest of each side (8 ms ÷ 2 ms)
        slow = rounds_run("BM_A", [0.010, 0.008, 0.009])
        fast = rounds_run("BM_A", [0.002, 0.003])
        self.assertAlmostEqual(bench_report.times_faster(slow, fast), 4.0, places=12)

    def test_medians_of_repetitions(self):
        data = {"benchmarks": [aggregate("BM_A", "median", 0.010), aggregate("BM_B", "median", 0.0025)]}
        runs = bench_report.runs_of(data)
        self.assertAlmostEqual(bench_report.times_faster(runs["BM_A"], runs["BM_B"]), 4.0, places=12)

    def test_missing_time_gives_none(self):
        slow = rounds_run("BM_A", [0.010])
        fast = rounds_run("BM_A", [0.0])
        self.assertIsNone(bench_report.times_faster(slow, fast))


class RunsOf(unittest.TestCase):
    def test_single_runs_keep_the_fastest_and_every_round(self):
        run = rounds_run("BM_A/real_time", [0.003, 0.001, 0.002], cpu_seconds=[0.0031, 0.0011, 0.0021])
        self.assertAlmostEqual(run.seconds, 0.001)
        for got, want in ((run.rounds, [0.003, 0.001, 0.002]), (run.cpu_rounds, [0.0031, 0.0011, 0.0021])):
            self.assertEqual(len(got), len(want))
            for g, w in zip(got, want):
                self.assertAlmostEqual(g, w, places=15)
        # sample standard deviation of 1, 2, 3 ms over their mean 2 ms
        self.assertAlmostEqual(run.cv, 0.5, places=12)

    def test_a_benchmark_without_real_time_is_timed_by_its_cpu_time(self):
        run = rounds_run("BM_A", [0.003], cpu_seconds=[0.002])
        self.assertAlmostEqual(run.seconds, 0.002)

    def test_median_wins_over_single_runs_of_the_same_name(self):
        data = {"benchmarks": [aggregate("BM_A", "median", 0.004), single("BM_A", 0.001)]}
        run = bench_report.runs_of(data)["BM_A"]
        self.assertAlmostEqual(run.seconds, 0.004)
        self.assertIsNone(run.rounds)

    def test_failed_runs_are_left_out(self):
        bad = single("BM_A", 0.001)
        bad["error_occurred"] = True
        self.assertEqual(bench_report.runs_of({"benchmarks": [bad]}), {})

    def test_rate_per_substep(self):
        run = rounds_run("BM_A", [0.002], points=100, substeps=10)
        self.assertAlmostEqual(run.step_seconds, 0.0002)
        self.assertAlmostEqual(run.cpu_rate, 100 * 10 / 0.002)


class ScenesAgainstTheirSheetsAlone(unittest.TestCase):
    """A many-sheet scene's verdict names the most × its sheets alone leave to contact work."""

    SCENE = "BM_Scene/rain_torus/threads:1/min_time:1.000"
    ALONE = "BM_SceneSheetsAlone/rain_torus/threads:1/min_time:1.000"

    @staticmethod
    def scene_run(name, seconds):
        run = single(name, seconds, points=4866, substeps=3330)
        run.update(sheets=36, simulated_s=0.999, s_per_simulated_s=seconds / 0.999)
        return run

    def report(self, with_alone=True):
        today = [self.scene_run(self.SCENE, 0.5)] + ([self.scene_run(self.ALONE, 0.25)] if with_alone else [])
        baseline = {"commit": "0598513000", "results": {"benchmarks": [self.scene_run(self.SCENE, 0.6)]}}
        report = bench_report.Report({}, bench_report.runs_of({"benchmarks": today}), ".", ".", ".",
                                     scenes_baseline=baseline)
        report.scenes()
        return report

    def test_the_bound_is_the_baseline_over_the_sheets_alone(self):
        report = self.report()
        # 0.6 s against 0.5 s is 1.2×, 8.3× short of 10×; 0.6 s over the sheets' 0.25 s is 2.4×
        [(what, value, goal, verdict, by)] = report.targets
        self.assertEqual(value, "1.20×")
        self.assertEqual(by, "8.3× short; its sheets alone allow 2.4×")
        row = next(line for line in report.lines if line.startswith("| rain_torus | 1 |"))
        self.assertTrue(row.endswith("| 2.4× |"), row)

    def test_without_the_sheets_alone_no_bound_is_claimed(self):
        [(_, _, _, _, by)] = self.report(with_alone=False).targets
        self.assertEqual(by, "8.3× short")

    def test_a_scene_file_the_baseline_ran_without_a_newer_key_is_also_divided_like_for_like(self):
        # the baseline ran the scene without contact_rims in 0.6 s; today's engine takes 0.75 s
        # with it (0.6 / 0.75 = 0.80×, 12.5× short of 10×) and 0.48 s without it, as the baseline
        # ran it (0.6 / 0.48 = 1.25×); the sheets alone 0.25 s (2.4×). A scene whose file
        # the baseline ran as it is (fig05) shows one figure in both columns.
        fig05 = "BM_Scene/fig05/threads:1/min_time:1.000"
        few = self.scene_run(fig05, 0.3)
        few.update(sheets=5)  # not a many-sheet scene: no verdict of its own
        today = [self.scene_run(self.SCENE, 0.75), self.scene_run(self.ALONE, 0.25), few]
        baseline = {"commit": "0598513000", "newer_keys_removed": {"rain_torus": ["contact_rims"]},
                    "results": {"benchmarks": [self.scene_run(self.SCENE, 0.6), self.scene_run(fig05, 0.6)]},
                    "current_without_newer_keys": {"results": {"benchmarks": [self.scene_run(self.SCENE, 0.48)]}}}
        report = bench_report.Report({}, bench_report.runs_of({"benchmarks": today}), ".", ".", ".",
                                     scenes_baseline=baseline)
        report.scenes()
        [(what, value, goal, verdict, by)] = report.targets
        self.assertEqual(value, "0.80×")
        self.assertEqual(by, "12.5× short; its sheets alone allow 2.4×; like for like (without contact_rims) 1.25×")
        row = next(line for line in report.lines if line.startswith("| rain_torus | 1 |"))
        self.assertIn("| 0.80× | 1.25× |", row)
        row = next(line for line in report.lines if line.startswith("| fig05 | 1 |"))
        self.assertIn("| 2.00× | 2.00× |", row)
        self.assertTrue(any("`contact_rims`" in line for line in report.lines))


class WorldOverheadFromPairedRounds(unittest.TestCase):
    """Issue 6's overhead of the World around the bare kernel is judged from tools/floor_pair.py's
    alternating rounds when they ran both, not from the main run's repetitions minutes apart."""

    BARE, KERNEL = "BM_Feature_bare", "BM_Feature_kernel_only"

    def overhead(self, floor):
        # the main run: a slow spell made the bare world's median 20 % slower than the kernel's
        today = [aggregate(self.BARE, "median", 0.0012), aggregate(self.KERNEL, "median", 0.001)]
        for entry in today:  # the feature table's rates: 1,024 points a substep
            entry["point_steps_per_s"] = 1024 / (entry["cpu_time"] * 1e-3)
        report = bench_report.Report({}, bench_report.runs_of({"benchmarks": today}), ".", ".", ".", floor=floor)
        report.plt = None  # no figure written
        report.features()
        [target] = [t for t in report.targets if t[0].startswith("World without obstacles")]
        return target

    def test_the_rounds_decide_where_both_ran_in_them(self):
        # three rounds: bare 1.01, 1.30 (one slow round), 1.02 ms against the kernel's 1.00 each time
        floor = {"benchmarks": [single(self.BARE, s) for s in (0.00101, 0.0013, 0.00102)] +
                               [single(self.KERNEL, 0.001) for _ in range(3)]}
        _, value, _, verdict, _ = self.overhead(floor)
        self.assertEqual(value, "+2.0 %")  # the median of 1.01, 1.30, 1.02
        self.assertEqual(verdict, bench_report.verdict(True))

    def test_without_rounds_of_both_the_main_run_decides(self):
        floor = {"benchmarks": [single(self.BARE, s) for s in (0.00101, 0.00102)]}  # no kernel rounds
        _, value, _, verdict, by = self.overhead(floor)
        self.assertEqual(value, "+20.0 %")
        self.assertEqual(verdict, bench_report.verdict(False))
        self.assertEqual(by, "15.0 points over")
        self.assertEqual(self.overhead(None)[1], "+20.0 %")


class SpeedupShortfall(unittest.TestCase):
    def test_a_ratio_just_under_its_goal_is_short_by_a_named_amount(self):
        # 2.995× shows as 3.00× at two decimals; 3 / 2.995 is 0.17 % more
        self.assertEqual(bench_report.speedup_shortfall(2.995, 3.0), "0.17 % short")
        self.assertEqual(bench_report.speedup_shortfall(2.8, 3.0), "7.1 % short")

    def test_a_ratio_far_from_its_goal_is_short_by_a_times(self):
        self.assertEqual(bench_report.speedup_shortfall(1.2, 10.0), "8.3× short")

    def test_a_met_or_unmeasured_target_has_no_shortfall(self):
        self.assertEqual(bench_report.speedup_shortfall(3.0, 3.0), "")
        self.assertEqual(bench_report.speedup_shortfall(None, 3.0), "")


class Slope(unittest.TestCase):
    def test_power_law(self):
        xs = [16, 32, 64, 128]
        self.assertAlmostEqual(bench_report.loglog_slope(xs, [3 * x ** 1.5 for x in xs]), 1.5, places=12)

    def test_one_size_has_no_slope(self):
        self.assertTrue(math.isnan(bench_report.loglog_slope([8, 8], [1, 2])))


if __name__ == "__main__":
    unittest.main()
