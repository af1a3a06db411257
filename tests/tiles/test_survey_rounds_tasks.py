"""The survey's two rounds as tasks on scratch files: certificates that widen, and the same fits either way."""

import json

import numpy as np
import pytest
from tiles_helpers import exact

from heatcurv.errors import HeatcurvError
from heatcurv.tiles import compute, tasks
from heatcurv.tiles.plan import distinct_frame, make_tiling, read_rows, scan_stats, scatter
from heatcurv.tiles.sources import open_source

OPTIONS = {"method": "default", "workers": 1}


@pytest.fixture(scope="module")
def scratch(torus_file, tmp_path_factory):
    """The 6000-point torus tiled into scratch files (the driver's three passes), and each tile's keys."""
    work = tmp_path_factory.mktemp("rounds")
    source = open_source(torus_file[0])
    stats = scan_stats(source)
    tiling = make_tiling(source, stats, 1200)
    scatter(source, tiling, work)
    stats = distinct_frame(work, tiling, stats)
    (work / "plan.json").write_text(json.dumps({"tiling": tiling.to_json(), "stats": stats.__dict__}))
    keys = []
    for t in range(len(tiling.counts)):
        core, _ = read_rows(work, int(tiling.offsets[t]), int(tiling.offsets[t + 1]))
        spec = tasks.KeysTask(str(work), t, OPTIONS, stats, compute.key_halo(core, OPTIONS))
        keys.append(tasks.run_keys(spec))
    return work, stats, tiling, keys


def test_keys_widen_a_halo_too_thin_and_give_the_same_candidates(scratch, monkeypatch):
    work, stats, tiling, keys = scratch
    calls = []
    real = compute.key_tile

    def counted(points, core, *args):
        calls.append(len(points) - int(core.sum()))
        return real(points, core, *args)

    monkeypatch.setattr(compute, "key_tile", counted)
    spec = tasks.KeysTask(str(work), 3, OPTIONS, stats, halo=1e-6)
    thin = tasks.run_keys(spec)  # a halo of nothing: the certificate widens it
    assert len(calls) == 2 and calls[0] == 0 and calls[1] > 0
    np.testing.assert_array_equal(thin.keys, keys[3].keys)
    np.testing.assert_array_equal(thin.positions, keys[3].positions)


def test_centres_widen_a_guess_too_small_and_fit_the_same_numbers(scratch, monkeypatch):
    work, stats, tiling, keys = scratch
    plan = compute.plan_centres(keys, stats, OPTIONS)
    tile = int(np.bincount(plan.tile).argmax())
    places = plan.of_tile(tile)
    spec = tasks.CentresTask(str(work), tile, OPTIONS, stats, plan, places)
    right = tasks.run_centres(spec)
    guesses = []
    real = compute.centre_reach

    def small(*args):
        guesses.append(real(*args) * 0.3)
        return guesses[-1]

    monkeypatch.setattr(compute, "centre_reach", small)
    widened = tasks.run_centres(spec)
    assert len(right) == 1 and len(widened) >= 2  # the centres whose reach passed the guess were fitted again
    assert len(guesses) == 1 and np.any(right[0].reach * compute.cloud_frame(stats).unit > guesses[0])
    assert _by_place(widened) == _by_place(right)
    assert sorted(p for part in widened for p in part.places.tolist()) == places.tolist()
    # a guess that never grows enough fails with a message, never a wrong fit
    monkeypatch.setattr(compute, "HALO_MARGIN", 1e-3)
    with pytest.raises(HeatcurvError, match=f"survey of tile {tile}: the centres' certificate failed"):
        tasks.run_centres(spec)


def _by_place(parts):
    """``{(scale label, place): (mean, factor, sigma, h)}`` of a tile's parts."""
    out = {}
    for part in parts:
        for label, fits in part.fits.items():
            for i, place in enumerate(part.places[: fits.mean.shape[0]].tolist()):
                out[label, place] = tuple(float(getattr(fits, f)[i]) for f in ("mean", "factor", "sigma", "h"))
    return out


@pytest.mark.parametrize("tile_size, tiles, rounds",
                         [(4000, 2, ["run_survey"]), (1200, 8, ["run_keys", "run_centres"])])
def test_few_tiles_are_surveyed_in_one_round_many_in_two(torus_file, torus_memory, tmp_path, monkeypatch, tile_size,
                                                        tiles, rounds):
    from heatcurv.tiles import driver, job, phase_survey
    from support.tiles import tiled_agreement

    phases = []
    real_run = job.submit

    def run(executor, workers, fn, *args):
        phases.append(fn.__name__)
        return real_run(executor, workers, fn, *args)

    monkeypatch.setattr(job, "submit", run)
    monkeypatch.setattr(phase_survey, "ONE_ROUND_TILES", 2)  # the default (64): one round here
    out = tmp_path / "torus.ply"
    report = driver.compute_file(torus_file[0], out, tile_size=tile_size, tile_workers=2, scheduler="threads",
                                 dtype="float64", max_memory="4G")
    assert report.tiles == tiles and phases == rounds + ["run_tile"]
    # either way every field equals the in-memory run's bit for bit (measured)
    agreement = tiled_agreement(out, torus_memory, rtol=0.0)
    assert exact(agreement) == dict.fromkeys(agreement, (0, 0.0))


@pytest.mark.parametrize("noise, rounds", [(0.0, ["run_keys", "run_centres"]),
                                           (0.0012, ["run_keys", "run_centres", "run_centres"])])
def test_round_two_fits_the_gate_first_and_every_candidate_only_under_noise(tmp_path, monkeypatch, noise, rounds):
    import heatcurv
    from heatcurv.tiles import driver, job, phase_survey
    from support.tiles import tiled_agreement

    sample = heatcurv.surfaces.Torus().sample(6000, "random", seed=3)
    diagonal = np.linalg.norm(np.ptp(sample.points, axis=0))
    points = sample.points + np.random.default_rng(3).normal(scale=noise * diagonal, size=sample.points.shape)
    src = tmp_path / "torus.npy"
    np.save(src, points)
    phases = []
    real_run = job.submit

    def run(executor, workers, fn, specs, *args):
        phases.append((fn.__name__, {getattr(spec, "levels", None) for spec in specs.values()}))
        return real_run(executor, workers, fn, specs, *args)

    monkeypatch.setattr(job, "submit", run)
    monkeypatch.setattr(phase_survey, "ONE_ROUND_TILES", 2)
    out = tmp_path / "torus.ply"
    driver.compute_file(src, out, tile_size=1200, tile_workers=2, scheduler="threads", dtype="float64",
                        max_memory="4G")
    assert [name for name, _ in phases] == rounds + ["run_tile"]
    # the gate's round fits the chord and the ladder's first candidate; a noisy cloud's then fits them all
    assert phases[1][1] == {heatcurv.choice.survey.GATE_LEVELS} and (noise == 0.0 or phases[2][1] == {None})
    # bit for bit (measured), clean or noisy, the points whose side the whole cloud's winding number contradicts
    # (a noisy level here and there) flagged alike: every tile's share of the sources is the in-memory run's
    memory = heatcurv.estimate(points)
    agreement = tiled_agreement(out, memory, rtol=0.0)
    differ = exact(agreement)
    assert differ == dict.fromkeys(differ, (0, 0.0))
