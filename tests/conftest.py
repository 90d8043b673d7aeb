"""How ``scripts/test`` spreads the suite over its workers (pytest-xdist, ``--dist loadfile``).

Every test file is one unit of work, so a module fixture is built once, except that files which
share a session-cached scan or map (``helpers.visual_scene``, ``helpers.fast_scan``,
``robot_helpers.scan_and_map``) form one unit: one worker builds the scan once for all of them
instead of each worker building its own. Units are handed out longest first (the costs below,
CPU seconds measured on one thread), so the heavy files do not start last and leave one worker
idle while the other finishes them. A file missing from the table counts as cheap. This changes
only which worker runs a test and when, never what it asserts.
"""

import pytest

#: files that share a cached scan or map: they run on one worker, one after another
FAMILIES = {
    "fast_scan": (
        "test_scan.py",
        "test_ground_truth.py",
        "test_eval_parallel.py",
        "test_encoders_registry.py",
    ),
    "robot_scan": ("test_robot_api.py", "test_robot_obstacles.py", "test_franky_driver.py"),
    "visual_scene": (
        "test_visual_database.py",
        "test_visual_localize.py",
        "test_visual_photometric.py",
    ),
}

#: approximate cost [CPU s] of the heaviest files (``--durations``, one math thread)
COSTS = {
    "test_avlmap.py": 228,
    "test_eval_runner.py": 171,  # its robustness sweep is marked slow
    "test_eval_parallel.py": 10,  # its serial-against-parallel runs are marked slow
    "test_kind_reader.py": 12,  # its refit reproducing the committed reader is marked slow
    "test_encoders_registry.py": 10,  # fast_scan's; its default map build is marked slow
    "test_instance_eval.py": 90,  # marked slow: run by scripts/test -m slow
    "test_franky_driver.py": 40,  # franky-sim in real time and a reach; robot_scan's map
    "test_scan.py": 77,  # with test_ground_truth.py: one scan for both
    "test_robot_api.py": 76,  # with test_robot_obstacles.py, test_franky_driver.py
    "test_visual_localize.py": 61,  # with test_visual_database.py, test_visual_photometric.py
    "test_robot_mobile_room.py": 62,
    "test_viewer.py": 60,  # a map, a headless browser drawing it in software
    "test_fuzz_sandbox.py": 50,
    "test_import.py": 60,  # a 70-frame scan, three small oracle maps, 14 checked imports
    "test_encoders_openclip.py": 36,
    "test_encoders_audio.py": 34,
    "test_fuzz_cli.py": 27,
    "test_places.py": 25,  # MiniLM on about 600 phrases, two small fits
    "test_hardening_probe.py": 15,  # one two-frame oracle map
    "test_sound_bank.py": 27,
    "test_registration.py": 26,
    "test_encoders_vision.py": 22,
    "test_room_scan.py": 14,
    "test_fuzz_loaders.py": 13,
    "test_arm_reach.py": 13,
    "test_visual_panorama.py": 10,
    "test_cli_room.py": 9,
    "test_object_module.py": 8,
    "test_room.py": 8,
}

_FAMILY_OF = {f: name for name, files in FAMILIES.items() for f in files}


def _unit(item) -> str:
    name = item.path.name
    return _FAMILY_OF.get(name, name)


def _cost(unit: str) -> float:
    files = FAMILIES.get(unit, (unit,))
    return sum(COSTS.get(f, 0.0) for f in files)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile`` with the families above as single units, in collection order."""
    if config.getoption("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class FileFamilyScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return _FAMILY_OF.get(path.rsplit("/", 1)[-1], path)

    config.option.loadscopereorder = False  # keep the longest-first order of the collection
    return FileFamilyScheduling(config, log)


def pytest_collection_modifyitems(config, items):
    if not hasattr(config, "workerinput"):
        return  # only xdist's workers, whose collection the scheduler hands out
    # Longest first; a stable sort keeps each file's tests in their order.
    first = {}
    for i, item in enumerate(items):
        first.setdefault(_unit(item), i)
    items.sort(key=lambda it: (-_cost(_unit(it)), first[_unit(it)]))
