"""The survey's context in scratch: a typed, frozen dataclass written as JSON and read back to the same bits."""

import dataclasses
import json
import struct

import numpy as np
import pytest

import heatcurv
from heatcurv.errors import HeatcurvError
from heatcurv.tiles import compute_file, phase_survey
from heatcurv.tiles.context import SurveyContext, from_plain, read_context, to_plain, write_context


def _same(a, b, where="context"):
    """Assert ``b`` is ``a`` read back: the same types, dtypes, shapes and bits (numpy scalars as Python numbers)."""
    if isinstance(a, np.generic):
        a = a.item()
    assert type(a) is type(b), f"{where}: {type(a).__name__} came back as {type(b).__name__}"
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            _same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, np.ndarray):
        assert (a.dtype, a.shape) == (b.dtype, b.shape), where
        assert a.tobytes() == b.tobytes(), where
    elif isinstance(a, float):
        assert struct.pack("<d", a) == struct.pack("<d", b), where
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, dict):
        assert list(a) == list(b), where
        for k in a:
            _same(a[k], b[k], f"{where}[{k!r}]")
    else:
        assert a == b, where


@pytest.mark.parametrize("rounds", [1, 2])
def test_the_context_is_written_as_json_and_read_back_to_the_bit(tmp_path, monkeypatch, rounds):
    """A noisy torus (its kernel widths chosen at sample centres: arrays in the context), surveyed in one round and
    in two; the run stops once the context is written."""
    sample = heatcurv.surfaces.Torus(0.6, 1.4).sample(4000, "random", seed=5)
    rng = np.random.default_rng(5)
    points = sample.points + rng.normal(scale=0.0012 * 4.4, size=sample.points.shape) + [5e5, 4e6, 90.0]
    src = tmp_path / "noisy.npy"
    np.save(src, points)
    written = []

    def write_and_read(path, context):
        write_context(path, context)
        written.append((context, read_context(path), json.loads(open(path).read())))
        raise HeatcurvError("stop after the survey")

    monkeypatch.setattr(phase_survey, "write_context", write_and_read)
    monkeypatch.setattr(phase_survey, "ONE_ROUND_TILES", 63 if rounds == 1 else 2)
    with pytest.raises(HeatcurvError, match="stop after the survey"):
        compute_file(src, tmp_path / "noisy.ply", tile_size=1000, tile_workers=1, scheduler="serial",
                     max_memory="4G")
    context, again, plain = written[0]
    assert isinstance(context, SurveyContext) and plain["type"] == "SurveyContext"
    with pytest.raises(dataclasses.FrozenInstanceError):
        context.halo = 0.0
    scale = context.choices.scale
    assert scale.k_centre is not None and scale.centres.shape == (len(scale.k_centre), 3) and scale.k_centre.max() > 60
    _same(context, again)


def test_a_context_holds_only_its_own_types(tmp_path):
    with pytest.raises(TypeError, match="a context cannot hold a set"):
        to_plain({"a": {1, 2}})
    with pytest.raises(TypeError, match="a context cannot hold a .*Tiling"):
        from heatcurv.tiles.plan import Tiling

        to_plain(Tiling((0, 0, 0), (1, 1, 1), (1, 1, 1), [], []))
    plain = to_plain({"k": np.arange(3, dtype=np.int32), "x": np.float64(np.nan)})
    back = from_plain(json.loads(json.dumps(plain)))
    assert back["k"].dtype == np.int32 and back["k"].tolist() == [0, 1, 2] and np.isnan(back["x"])
    bad = tmp_path / "context.json"
    bad.write_text('{"type": "Tiling", "fields": {}}')
    with pytest.raises(HeatcurvError, match=r"cannot read the survey's context .*context\.json: 'Tiling'; delete"):
        read_context(bad)
    bad.write_text("[1, 2]")
    with pytest.raises(HeatcurvError, match="it holds a list"):
        read_context(bad)


def test_the_plan_is_a_frozen_dataclass_written_as_json():
    from heatcurv.tiles.plan import CloudStats, TilePlan, Tiling

    tiling = Tiling((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (40, 10, 1), [(0, 0, 0, 20, 10, 1), (20, 0, 0, 40, 10, 1)],
                    [2000, 2000])
    stats = CloudStats(4000, 4000, (0.0, 0.0, 0.0), (40.0, 10.0, 1.0), (20.0, 5.0, 0.5), 0.1 + 0.2, 3999)
    plan = TilePlan({"version": 7, "options": "abc"}, tiling, stats, 2000, (2.5, 1 / 3), (0.25, 0.5))
    with pytest.raises(dataclasses.FrozenInstanceError):
        plan.tile_size = 1000
    data = json.loads(json.dumps(plan.to_json()))
    # the layout the tasks read (heatcurv.tiles.tasks.load_plan)
    assert data["stats"]["low"] == [0.0, 0.0, 0.0] and data["tiling"]["counts"] == [2000, 2000]
    assert data["survey_halos"] == [2.5, 1 / 3]
    assert TilePlan.from_json(data) == plan


def test_a_clean_clouds_first_halo_is_three_of_its_largest_operator_balls(torus_file, tmp_path):
    # the chosen kernel is the operator's: its largest ball over every point (not over the surveyed centres,
    # which the key bound thins: a halo that moved with them moved the tiled orientation's patches)
    from heatcurv.choice.survey import tile_options
    from heatcurv.operators.operator import HeatKernelOperator
    from heatcurv.tiles.compute import HALO_MARGIN

    report = compute_file(torus_file[0], tmp_path / "t.ply", tile_size=1500, scheduler="serial", max_memory="4G")
    assert report.context["kernel"] == "chord-60"
    op = HeatKernelOperator.from_points(torus_file[1].points, tile_options({}))
    largest = float(op.neighbourhood.radius.max()) * op.prepared.unit
    assert report.halo == pytest.approx(3.0 * largest * HALO_MARGIN, rel=1e-12)
