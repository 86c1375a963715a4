"""Each kind of light map is one record (addon/bake/kinds.py) that options, cost and the bake read."""
import dataclasses
import math

import numpy as np
import pytest

from addon.bake import cost, kinds, options
from addon.bake.kinds import KINDS, Kind
from addon.core import lightmap


@pytest.mark.parametrize("kind", list(KINDS))
def test_every_kind_record_is_complete(kind):
    record = KINDS[kind]
    assert record.id == kind and record.label and record.description
    for field in dataclasses.fields(Kind):
        if field.name not in ("pass_filter", "variance", "scale_option", "combine"):
            assert getattr(record, field.name) is not None, field.name
    assert record.bake_type in ("AO", "DIFFUSE", "EMIT", "COMBINED", "SHADOW", "NORMAL")
    assert (record.channels in ("Y", "RGB") or record.bakes) and record.scale > 0
    assert (record.combine is not None) == bool(record.bakes)
    assert record.bytes_per_texel > 0 and record.seconds_per_texel_sample > 0
    lo, hi = record.value_range
    assert hi is None or hi > lo
    assert record.quantity and record.units and record.attribute.startswith("IL ")
    assert callable(record.smallest_target_error) and callable(record.preview)
    assert record.smallest_target_error(4096) >= lightmap.SMALLEST_TARGET_ERROR
    assert "{" not in record.target_limit.format(max_samples=4096)
    assert record.variance is None or callable(record.variance)
    assert record.estimate in ("binomial", "none")
    values = np.full((2, 3) + ((len(record.channels),) if len(record.channels) > 1 else ()), 0.5, np.float32)
    shown = record.preview(values)
    assert shown.shape == (values.shape if not record.bakes else (2, 3, 3)) and np.isfinite(shown).all()
    channels = record.exr_channels(values, np.ones((2, 3), np.float32))
    assert list(channels) == [*record.channels, "A"] and np.array_equal(record.from_exr(channels), values)
    rgba = np.full((2, 3, 4), 0.25, np.float32)
    if record.bakes:            # read per Cycles call, then combined
        parts = [bake.read(rgba) for bake in record.bakes]
        assert record.combine(parts).shape == values.shape
        return
    assert record.read(rgba).shape == values.shape
    assert np.allclose(record.read(rgba), 0.25 * (record.scale if len(record.channels) > 1 else 1.0))


def test_the_two_kinds_are_as_designed():
    ao, irradiance = KINDS["ao"], KINDS["irradiance"]
    assert list(KINDS) == ["ao", "irradiance", "directional"]
    assert (ao.bake_type, ao.pass_filter, ao.bounces, ao.lit, ao.halves) == ("AO", None, False, False, False)
    assert (irradiance.bake_type, irradiance.bounces, irradiance.lit, irradiance.halves) == \
        ("DIFFUSE", True, True, True)
    assert ao.scale == 1.0 and irradiance.scale == math.pi
    assert ao.variance is lightmap.per_sample_variance_ao and irradiance.variance is None
    assert ao.value_range == (0.0, 1.0) and irradiance.value_range == (0.0, None)

    class Opts:
        bounces = 0
    assert ao.cycles_bounces(Opts) == (0, 0) and irradiance.cycles_bounces(Opts) == (0, 1)
    assert ao.cycles_pass_filter(Opts) is None and irradiance.cycles_pass_filter(Opts) == {"DIRECT"}
    Opts.bounces = 3
    assert ao.cycles_bounces(Opts) == (0, 0) and irradiance.cycles_bounces(Opts) == (3, 3)
    assert irradiance.cycles_pass_filter(Opts) == {"DIRECT", "INDIRECT"}


def test_options_and_cost_take_their_values_from_the_records(monkeypatch):
    assert [c[0] for c in options.MAP_CHOICES] == list(KINDS) and options.MAPS == tuple(KINDS)
    assert all(c == (k.id, k.label, k.description) for c, k in zip(options.MAP_CHOICES, KINDS.values()))
    for kind, record in KINDS.items():
        assert cost.per_texel([kind]) == record.bytes_per_texel
        assert cost.PLAIN.rate(kind) == record.seconds_per_texel_sample
        assert cost.calls(16, kind, 8) == (2 if record.halves else 1)
    monkeypatch.setitem(KINDS, "ao", dataclasses.replace(KINDS["ao"], bytes_per_texel=7, halves=True))
    assert cost.per_texel(["ao"]) == 7 and cost.calls(16, "ao", 8) == 2


def test_the_bake_modules_take_their_values_from_the_records(monkeypatch):
    from addon.bake import materials, passes

    class Opts:
        samples, seed = 8, 3
    for kind, record in KINDS.items():
        assert callable(getattr(materials, record.material))
        assert len(passes.fixed_calls(kind, Opts)) == (2 if record.halves else 1)
    monkeypatch.setitem(KINDS, "ao", dataclasses.replace(KINDS["ao"], value_range=(0.0, 0.5), variance=None,
                                                         estimate="none"))
    values, mask = np.full((2, 2), 0.4, np.float32), np.ones((2, 2), bool)
    assert math.isnan(passes.estimated("ao", Opts, [(values, mask)])[3])


def test_target_error_limits_come_from_the_records():
    from addon.bake import BakeOptions
    from addon.core.errors import InputError
    opts = BakeOptions(target_error=1e-4, max_samples=4096)
    with pytest.raises(InputError, match="for ao within 4096 samples"):
        opts.check_target(["ao"])
    opts.check_target(["irradiance"])
    with pytest.raises(InputError, match="in float32 maps"):
        BakeOptions(target_error=1e-300).check_target(["irradiance"])
    assert kinds.KINDS["ao"].smallest_target_error(4096) == 0.5 / 4096
