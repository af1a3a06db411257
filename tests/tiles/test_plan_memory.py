"""The plan's memory model: each phase's workers are budgeted with that phase's halo, the survey's included."""

import numpy as np
import pytest
from tiles_helpers import ALL_FIELDS, exact, read_fields

from heatcurv.errors import HeatcurvError
from heatcurv.tiles import plan
from heatcurv.tiles.plan import (
    DRIVER_MEMORY,
    CloudStats,
    Tiling,
    fitting_workers,
    halo_points,
    read_rows,
    worker_memory,
)
from heatcurv.tiles.tasks import load_plan
from support.tiles import tiled_agreement


def _two_tiles():
    """A 40 x 10 x 1 slab of 4000 points cut into two 20 x 10 x 1 tiles of 2000 (uniform density 10 per m^3)."""
    tiling = Tiling((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (40, 10, 1), [(0, 0, 0, 20, 10, 1), (20, 0, 0, 40, 10, 1)],
                    [2000, 2000])
    stats = CloudStats(4000, 4000, (0.0, 0.0, 0.0), (40.0, 10.0, 1.0), (20.0, 5.0, 0.5))
    return tiling, stats


def test_halo_points_count_what_a_halo_box_adds_inside_the_cloud():
    tiling, stats = _two_tiles()
    # a halo of 5: each tile's box grows by 5 towards the other tile only (the cloud's box clips the rest),
    # 20 -> 25 along x: 2000 x 25 / 20 points
    assert halo_points(tiling, stats, 5.0).tolist() == [2500, 2500]
    # one halo per tile (the survey's are measured tile by tile); NaN is no halo
    assert halo_points(tiling, stats, [5.0, 0.0]).tolist() == [2500, 2000]
    assert halo_points(tiling, stats, float("nan")).tolist() == [2000, 2000]
    # a halo past the whole cloud: every point
    assert halo_points(tiling, stats, 100.0).tolist() == [4000, 4000]


def test_the_survey_halo_is_budgeted_as_the_tiles_halo_is():
    tiling, stats = _two_tiles()
    tiles_halo, survey_halo = 2.0, 10.0  # a survey's halo is the widest candidate's ball: wider
    tiles_points, survey_points = halo_points(tiling, stats, tiles_halo), halo_points(tiling, stats, survey_halo)
    assert survey_points.tolist() == [3000, 3000] and tiles_points.tolist() == [2200, 2200]
    # a budget holding the driver and two workers of the tiles' halo, but not two of the survey's
    budget = DRIVER_MEMORY + 2 * worker_memory(2200)
    assert budget < DRIVER_MEMORY + 2 * worker_memory(3000)
    assert fitting_workers(tiles_points, budget, 2, 2, 2000) == 2
    assert fitting_workers(survey_points, budget, 2, 2, 2000, "survey") == 1
    # each worker's estimate is the model's: overhead plus bytes per point of core and halo
    assert worker_memory(3000) == plan.WORKER_OVERHEAD + plan.BYTES_PER_POINT * 3000


def test_a_survey_halo_that_leaves_no_worker_is_an_error():
    tiling, stats = _two_tiles()
    budget = DRIVER_MEMORY + worker_memory(2500)
    assert fitting_workers(halo_points(tiling, stats, 5.0), budget, 2, 2, 2000, "survey") == 1
    with pytest.raises(HeatcurvError, match=r"a tile of about 3000 points \(core and halo, the survey\) needs about "
                                            r".*pass a smaller --tile-size \(now 2000\)"):
        fitting_workers(halo_points(tiling, stats, 10.0), budget, 2, 2, 2000, "survey")


def test_the_plan_holds_each_tiles_survey_halo_and_the_survey_runs_within_it(torus_file, tmp_path, monkeypatch):
    """compute_file decides the survey's halos before the survey, from each core, and budgets its workers with them."""
    from heatcurv.tiles import compute, driver, job, phase_survey

    phases = []
    real_run = job.submit

    def run(executor, workers, fn, specs, on_done, say, what, total):
        phases.append((fn.__name__, workers, {t: getattr(spec, "halo", None) for t, spec in specs.items()}))
        return real_run(executor, workers, fn, specs, on_done, say, what, total)

    monkeypatch.setattr(job, "submit", run)
    monkeypatch.setattr(phase_survey, "ONE_ROUND_TILES", 2)  # the survey in two rounds (the default for 65+ tiles)
    out = tmp_path / "torus.ply"
    report = driver.compute_file(torus_file[0], out, tile_size=1200, tile_workers=2, scheduler="threads",
                                 max_memory="4G", keep_scratch=True)
    saved = load_plan(report.scratch)
    tiling, stats = Tiling.from_json(saved["tiling"]), CloudStats(**{
        k: tuple(v) if isinstance(v, list) else v for k, v in saved["stats"].items()})
    expected = []
    for t in range(len(tiling.counts)):
        core, _ = read_rows(report.scratch, int(tiling.offsets[t]), int(tiling.offsets[t + 1]))
        expected.append(compute.survey_halo(core, stats, report.parameters["options"]))
    assert saved["survey_halos"] == expected
    # they are wider than the tiles' (the widest candidate against the chosen) and the keys' (one operator ball),
    # which the survey's first round got
    assert min(expected) > report.halo
    keys = [p for p in phases if p[0] == "run_keys"][0]
    assert [keys[2][t] for t in range(len(expected))] == saved["key_halos"]
    assert max(h / s for h, s in zip(saved["key_halos"], expected)) < 0.5
    # the same run with a model whose survey tiles no longer fit two at once runs the survey one at a time
    points = halo_points(tiling, stats, expected)
    tiles_points = halo_points(tiling, stats, report.halo)
    assert points.max() > tiles_points.max()
    per_point = 10_000
    budget = DRIVER_MEMORY + 2 * (plan.WORKER_OVERHEAD + per_point * int(tiles_points.max())) + 1
    assert budget < DRIVER_MEMORY + 2 * (plan.WORKER_OVERHEAD + per_point * int(points.max()))
    monkeypatch.setattr(plan, "BYTES_PER_POINT", per_point)
    phases.clear()
    again = driver.compute_file(torus_file[0], tmp_path / "again.ply", tile_size=1200, tile_workers=2,
                                scheduler="threads", max_memory=budget)
    assert [(name, workers) for name, workers, _ in phases] == [("run_keys", 1), ("run_centres", 1), ("run_tile", 2)]
    assert again.workers == 2
    first, second = read_fields(out), read_fields(tmp_path / "again.ply")  # the budget changes no value
    assert first.keys() == second.keys()
    for name in first:
        np.testing.assert_array_equal(first[name], second[name], err_msg=name)


# ---- the plan fits the budget by itself: fewer workers, then one in the driver's process, then smaller tiles ----


def test_the_issues_tile_runs_in_the_drivers_process_within_1g():
    """1 GiB leaves 424 MiB past the driver: no worker process of 400 MiB + a tile of 263658 points (core and the
    survey's halo, the tile the issue's 1M-point run was refused for), but the driver's own process holds it."""
    budget = plan.parse_size("1G")
    assert plan.phase_workers([263658], budget, 2, 2, in_process=False) is None
    fit = plan.phase_workers([263658], budget, 2, 2)
    assert fit == plan.PhaseWorkers(1, True, DRIVER_MEMORY + plan.BYTES_PER_POINT * 263658)
    assert fit.memory == 971_901_000 <= budget
    # workers are shrunk before anything else: two fit at 2.5 GiB, one at 1.5 GiB (each 762 MB with its process)
    assert plan.phase_workers([263658], plan.parse_size("2.5G"), 2, 2) == plan.PhaseWorkers(
        2, False, DRIVER_MEMORY + 2 * worker_memory(263658))
    assert plan.phase_workers([263658], plan.parse_size("1.5G"), 2, 2).count == 1
    # below what the driver and that tile need, the message names the budget that fits it
    error = plan.budget_refusal(263658, plan.parse_size("900M"), 10000, "survey", True)
    assert str(error) == (
        "a tile of about 263658 points (core and halo, the survey) needs about 972 MB with the driver, more than "
        "the budget of 944 MB leaves for one worker; pass a smaller --tile-size (now 10000) or a --max-memory of at "
        "least 927M (the model: the driver 629 MB, a worker process 419 MB, 1300 bytes per point of a tile's core "
        "and halo)")
    assert DRIVER_MEMORY + plan.BYTES_PER_POINT * 263658 <= plan.parse_size("927M")
    assert DRIVER_MEMORY + plan.BYTES_PER_POINT * 263658 > plan.parse_size("926M")


def _terrain(points: int, side: float, tile_size: int):
    """A flat square cloud of ``points`` points, ``side`` long, cut into k x k equal tiles of at most ``tile_size``."""
    k = int(np.ceil(np.sqrt(points / tile_size)))
    edges = np.linspace(0, 256, k + 1).round().astype(int)
    cells = [(int(edges[i]), int(edges[j]), 0, int(edges[i + 1]), int(edges[j + 1]), 1)
             for i in range(k) for j in range(k)]
    counts = [points * (c[3] - c[0]) * (c[4] - c[1]) // 256**2 for c in cells]
    tiling = Tiling((0.0, 0.0, 0.0), (side / 256, side / 256, 1.0), (256, 256, 1), cells, counts)
    stats = CloudStats(points, points, (0.0, 0.0, 0.0), (side, side, 1.0), (side / 2, side / 2, 0.5))
    return tiling, stats


def test_a_1m_point_terrain_is_planned_within_1g_in_fewer_smaller_tiles():
    """The benchmark's terrain (16 points per m^2, 250 m square) with a measured survey halo (24.3 m, the median
    of the tiles' at 1M points with a survey margin of 1.1; 25.9 m with today's 1.25, which plans the same 9 tiles
    within 1 GiB; the compute halo is narrower): within 1 GiB the plan runs it in 9 tiles in the driver's process;
    at 700 MiB in smaller tiles; below the minimum it says what would fit."""
    tried = []

    def measure(tile_size):
        tried.append(tile_size)
        tiling, stats = _terrain(1_000_000, 250.0, tile_size)
        return int(halo_points(tiling, stats, 24.3).max()), len(tiling.counts)

    budget = plan.parse_size("1G")
    room = budget - DRIVER_MEMORY
    assert plan.default_tile_size(room, 2) == 10_000  # no worker process fits a tile of 10000 and its halo ...
    assert plan.plan_workers(room, 2, 20_000, 2) == 0
    first = plan.default_tile_size(room, 1, in_process=True)  # ... so the default is what the driver's holds
    assert first == 170_998
    tile_size, tiles, fit = plan.fit_tiles(measure, first, budget, 2, 2)
    assert tried == [170_998] and (tile_size, tiles) == (170_998, 9)
    assert fit == plan.PhaseWorkers(1, True, 994_779_700) and fit.memory <= budget
    # a tighter budget: smaller tiles, each try at most half the last
    tried.clear()
    messages = []
    tile_size, tiles, fit = plan.fit_tiles(measure, first, plan.parse_size("700M"), 2, 2, say=messages.append)
    assert tried == [170_998, 49_038, 24_519, 12_259, 6129] and tiles == 169
    assert fit == plan.PhaseWorkers(1, True, 725_687_500) and fit.memory <= plan.parse_size("700M")
    assert messages[0] == ("a tile of 170998 points with the survey's halo (about 281257 points) does not fit the "
                           "budget of 734 MB: tiling again at 49038 points")
    # a given tile size is kept: the message says which budget it needs, or a smaller tile
    with pytest.raises(HeatcurvError, match=r"pass a smaller --tile-size \(now 170998\) or a --max-memory of at "
                                            r"least 949M"):
        plan.fit_tiles(measure, first, plan.parse_size("900M"), 2, 2, given=True)
    # below the smallest tiles' need, the refusal names the minimum budget (the halo's points stay)
    tried.clear()
    with pytest.raises(HeatcurvError, match=r"^a tile of about 50888 points \(core and halo, the survey\) needs "
                                            r"about 695 MB with the driver, more than the budget of 671 MB leaves for "
                                            r"one worker; the smallest tiles \(1000 points\) need a --max-memory of "
                                            r"at least 664M \(the model"):
        plan.fit_tiles(measure, first, plan.parse_size("640M"), 2, 2)
    assert tried == [170_998, 19_615, 6203, 2694, 1347, 1000]
    assert plan.fit_tiles(measure, 1000, plan.parse_size("664M"), 2, 2)[2].in_process


def test_the_smallest_budget_and_the_default_for_a_small_cloud(monkeypatch):
    # no tiled run fits below the driver and one tile of 1000 points without a halo
    assert plan.smallest_budget() == DRIVER_MEMORY + 1000 * plan.BYTES_PER_POINT == 630_445_600
    # a busy machine's 60 % share of 717 MB available (430 MB) is below that: a small cloud's default budget is
    # what it needs in the driver's process, while that much is available
    monkeypatch.setattr(plan, "available_memory", lambda: 717_000_000)
    assert plan.default_budget() == 430_200_000
    assert plan.default_budget(6000) == DRIVER_MEMORY + 6000 * plan.BYTES_PER_POINT == 636_945_600
    assert plan.default_budget(10**8) == DRIVER_MEMORY + 10_000 * plan.BYTES_PER_POINT  # at most a tile of 10000
    monkeypatch.setattr(plan, "available_memory", lambda: 500_000_000)
    assert plan.default_budget(6000) == 500_000_000  # never more than is available: such a run is refused
    monkeypatch.setattr(plan, "available_memory", lambda: 4 * 10**9)
    assert plan.default_budget(6000) == 2_400_000_000  # the share, when it is larger


def test_a_budget_no_worker_process_fits_runs_in_the_drivers_process(torus_file, torus_memory, tmp_path, monkeypatch):
    """700 MiB was refused (no 400 MiB worker fits beside the driver's 600 MiB); now the survey and the tiles run in
    this process, one tile at a time, and every field is the in-memory run's bit for bit."""
    from heatcurv.tiles import driver, job

    phases = []
    real_run = job.submit

    def run(executor, workers, fn, specs, on_done, say, what, total):
        phases.append((fn.__name__, workers))
        return real_run(executor, workers, fn, specs, on_done, say, what, total)

    monkeypatch.setattr(job, "submit", run)
    out = tmp_path / "torus.ply"
    report = driver.compute_file(torus_file[0], out, tile_size=1200, tile_workers=2, max_memory="700M",
                                 dtype="float64", fields=ALL_FIELDS)
    assert phases == [("run_survey", 1), ("run_tile", 1)]
    assert (report.tiles, report.workers, report.scheduler, report.budget) == (8, 1, "serial", 700 * 2**20)
    agreement = tiled_agreement(out, torus_memory, rtol=0.0)
    assert exact(agreement) == dict.fromkeys(agreement, (0, 0.0))


def test_a_budget_below_the_smallest_tile_is_refused_before_reading(torus_file, tmp_path):
    from heatcurv.tiles import compute_file

    with pytest.raises(HeatcurvError, match=r"^a memory budget of 629 MB is too small for a tiled run: the driver "
                                            r"keeps 629 MB and the smallest tile \(1000 points, no halo\) needs "
                                            r"1.3 MB; pass a --max-memory of at least 602M$"):
        compute_file(torus_file[0], tmp_path / "out.ply", max_memory="600M")
    assert list(tmp_path.iterdir()) == []
