"""The correlate/update stage options: one set of defaults for the CLI and ``modalab run``."""
import pytest

from modalab.core.errors import PlanError
from modalab.app.project import STAGE_OPTIONS
from modalab.app.stages import CorrelateOptions, UpdateOptions


def test_run_correlate_defaults_are_the_cli_defaults():
    opts = CorrelateOptions()
    proj = STAGE_OPTIONS["correlate"]
    for key, field in (("mac_min", "mac_min"), ("freq_weight", "freq_weight"), ("freq_window", "freq_window"),
                       ("map", "dofmap"), ("geometry", "geometry"), ("same_ids", "same_ids")):
        assert proj[key][1] == getattr(opts, field), key
    assert STAGE_OPTIONS["update"]["freq_sigma"][1] == UpdateOptions().freq_sigma is None


@pytest.mark.parametrize("kw", [{"dofmap": "map.toml", "same_ids": True}, {"geometry": "g.uff", "dofmap": "m.toml"}])
def test_one_way_of_mapping_only(kw):
    with pytest.raises(PlanError, match="give one of --map, --geometry and --same-ids"):
        CorrelateOptions(**kw)


@pytest.mark.parametrize("w", [0.0, -0.1, float("nan")])
def test_frequency_window_must_be_positive(w):
    with pytest.raises(PlanError, match="--freq-window"):
        CorrelateOptions(freq_window=w)
