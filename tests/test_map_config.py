"""MapConfig: every field round-trips, module configs nest, old flat files still read."""

import json

import pytest

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid
from tabletop.mapping import MapConfig
from tabletop.mapping.area_module import AreaConfig
from tabletop.mapping.audio_module import AudioConfig
from tabletop.mapping.audio_segments import NoiseGateConfig
from tabletop.mapping.object_module import ObjectConfig
from tabletop.mapping.visual import VisualLocalizationConfig
from tabletop.mapping.visual.module import VisualModuleConfig


def test_every_field_round_trips_through_json():
    c = MapConfig(
        grid=VoxelGrid(voxel_size=0.005),
        pixel_step=2,
        frame_step=3,
        categories=("mug", "table", "other"),
        major_decay=12.0,
        aux_decay=3.0,
        min_confidence=0.6,
        self_filter_margin=None,
        object=ObjectConfig(select_margin=0.2, background=("table", "other")),
        area=AreaConfig(top_score=0.7),
        audio=AudioConfig(gate=NoiseGateConfig(hold_s=0.5)),
        visual=VisualModuleConfig(VisualLocalizationConfig(matcher="sift", stride=7), 0.3),
    )
    back = MapConfig.from_dict(json.loads(json.dumps(c.to_dict())))
    assert back == c
    assert back.objects == ("mug",)
    assert MapConfig.from_dict(MapConfig(visual=None).to_dict()).visual is None


def test_a_localization_config_is_taken_as_the_visual_modules():
    c = MapConfig(visual=VisualLocalizationConfig(matcher="sift"))
    assert isinstance(c.visual, VisualModuleConfig) and c.visual.localization.matcher == "sift"


def test_old_flat_configs_still_read():
    old = {"select_margin": 0.25, "gate": {"hold_s": 0.4}, "image_target_px": 0.2, "frame_step": 2}
    c = MapConfig.from_dict(old)
    assert c.object.select_margin == 0.25 and c.audio.gate.hold_s == 0.4 and c.frame_step == 2


def test_bad_configs_name_the_problem():
    with pytest.raises(ConfigError, match="unknown map config fields"):
        MapConfig.from_dict({"voxel": 1})
    with pytest.raises(ConfigError, match="'other'"):
        MapConfig(categories=("mug",))
    with pytest.raises(ConfigError, match="positive rate"):
        MapConfig(major_decay=0.0)
    with pytest.raises(ConfigError, match="object must be ObjectConfig, got dict"):
        MapConfig(object={"select_margin": 0.1})


def test_eval_map_settings_reach_the_module_configs():
    from tabletop.cli.evaluate import parse_map_settings
    from tabletop.eval.harness import map_config

    s = parse_map_settings(["object.instances=false", "frame_step=2", "object.text_min=0.4"])
    assert s == {"object": {"instances": False, "text_min": 0.4}, "frame_step": 2}
    c = map_config(**s)
    assert (c.object.instances, c.object.text_min, c.frame_step) == (False, 0.4, 2)
    assert c.object.temperature == map_config().object.temperature  # the rest keeps defaults
    with pytest.raises(ConfigError, match="bogus"):
        map_config(**parse_map_settings(["object.bogus=1"]))
    with pytest.raises(ConfigError, match="FIELD=VALUE"):
        parse_map_settings(["instances"])
