"""Paraphrase suites (tabletop/eval/paraphrase.py): the bank's two pools are disjoint and share
nothing with training texts, generation is seeded and deterministic (on a ground truth built
from the scene spec, no scan), every instruction is kept as the bank words it (never filtered
through the reader), absent goals include places, and the shipped suites load, cover every
goal type with absent goals, and sit on seeds nothing else uses.

Failure messages name bank entries and goal ids, never held-out phrasings: the team must not
read them."""

import importlib
import pkgutil
import re
import tomllib
from collections import Counter

import numpy as np
import pytest

from tabletop.errors import AssetError, ConfigError
from tabletop.eval.paraphrase import (
    AREA_KEYS,
    HELDOUT_POOLS,
    MIN_ABSENT,
    POOL_SEEDS,
    POOLS,
    READ_HELDOUT_POOLS,
    SUITE_DIRS,
    TUNE_POOLS,
    bare_colour_word,
    load_bank,
    paraphrase_suite,
    suite_sections,
)
from tabletop.eval.suites import to_toml
from tabletop.eval.tasks import GOAL_TYPES, SceneRef, load_tasks
from tabletop.eval.truth import resolve_truth
from tabletop.paths import DATA_DIR
from tabletop.sim.catalog import COLORS, OBJECT_KINDS
from tabletop.sim.ground_truth import (
    AreaTruth,
    GroundTruth,
    SoundEventTruth,
    TableTruth,
)
from tabletop.sim.sound_bank import CAPTIONS, SoundBank
from tabletop.sim.world import object_truth

BANKS = {pool: load_bank(pool) for pool in POOLS}


# ---------------------------------------------------------------------------- texts
def bag(text: str) -> str:
    """A phrase as a sorted bag of words: case, punctuation, hyphens, articles and a leading
    "sound of" aside ("the wake-up alarm" = "a wake up alarm" = "alarm wake up")."""
    t = re.sub(r"[^a-z0-9' ]", " ", text.lower().replace("-", " "))
    t = re.sub(r"^\s*(?:(?:the|a|an)\s+)?(?:sound|noise)s?\s+of\s+", "", t)
    return " ".join(sorted(w for w in t.split() if w not in ("a", "an", "the")))


def norm(text: str) -> str:
    """Lower case, single spaces, no leading article: the same words in the same order."""
    return re.sub(r"^(?:(?:the|a|an)\s+)+", "", re.sub(r"\s+", " ", text.lower()).strip())


def _strings(obj, out: set) -> None:
    if isinstance(obj, str):
        out.add(obj)
    elif isinstance(obj, dict):
        for k, v in obj.items():
            _strings(k, out)
            _strings(v, out)
    elif isinstance(obj, (list, tuple, set, frozenset)):
        for x in obj:
            _strings(x, out)


def _module_texts(module) -> set:
    out: set = set()
    for name, v in vars(module).items():
        if not name.startswith("__"):
            _strings(v, out)
    return out


def training_texts() -> set:
    """Every text training or the maps' tuning uses, as bags: the string constants of the
    training modules (vision synonyms and templates, audio captions and paraphrases), of the
    catalog (colours) and of every mapping module, templates ("a {}") filled
    with every catalog label, labelled class and colour, the bank's captions and the audio
    trainer's phrasings of every category, and the data files the maps read
    (``tabletop/data/*.toml``: the kinds' descriptions)."""
    import tabletop.mapping
    import tabletop.sim.catalog as catalog
    import tabletop.train.audio as audio
    import tabletop.train.vision as vision

    texts = _module_texts(vision) | _module_texts(audio) | _module_texts(catalog)
    for m in pkgutil.walk_packages(tabletop.mapping.__path__, "tabletop.mapping."):
        texts |= _module_texts(importlib.import_module(m.name))
    for f in sorted(DATA_DIR.glob("*.toml")):  # texts the maps read (the kinds' descriptions)
        _strings(tomllib.loads(f.read_text()), texts)
    fillers = set(COLORS)
    for k in OBJECT_KINDS.values():
        fillers |= {k.label, *(f"{c} {k.label}" for c in k.colors)}
    texts |= fillers
    texts |= {t.format(f) for t in list(texts) if t.count("{}") == 1 for f in fillers}
    texts |= set(CAPTIONS.values())
    bank = SoundBank.default()
    for c in bank.categories:
        texts |= set(audio.phrases_for(c, bank.caption(c)))
    return {bag(t) for t in texts if isinstance(t, str) and t.strip()}


@pytest.fixture(scope="module")
def trained():
    return training_texts()


def _bank_entries(pool: str) -> dict[str, str]:
    """Every phrasing of a pool by entry name, instruction templates included."""
    b = BANKS[pool]
    out = dict(b.phrasings())
    for k, vs in b.instructions.items():
        for i, v in enumerate(vs):
            out[f"instructions.{k}[{i}]"] = v
    for i, f in enumerate(b.colour_forms):
        out[f"colour_forms[{i}]"] = f
    return out


# ---------------------------------------------------------------------------- the bank
def _categories_the_pools_word() -> set[str]:
    """The bank categories every pool words: those of the first three bank builds, the bank
    the pools were written for (it holds every category a scan inserts). A category built
    later is never played by a scan (scans insert the pinned categories), and a pool that does
    not word it never asks it as absent either (absent bank sounds come from the pool's own
    sounds), so the pools' suites are the same with or without it."""
    import json

    from tabletop.sim.sound_bank import DEFAULT_BANK_DIR

    doc = json.loads((DEFAULT_BANK_DIR / "manifest.json").read_text(encoding="utf-8"))
    return {c["category"] for c in doc["clips"] if c["batch"] <= 3}


def test_both_pools_cover_every_kind_colour_sound_area_and_instruction():
    bank = SoundBank.default()
    cats = _categories_the_pools_word()
    assert set(bank.scan_categories) <= cats <= set(bank.categories)
    for pool, b in BANKS.items():
        assert set(b.objects) == set(OBJECT_KINDS), pool
        assert set(b.colours) == set(COLORS), pool
        assert cats <= set(b.sounds), (pool, sorted(cats - set(b.sounds)))
        assert set(b.areas) == set(AREA_KEYS), pool
        assert len(b.absent_objects) >= 8 and len(b.absent_sounds) >= 6, pool
        for k, ph in b.objects.items():
            assert len(ph.names) >= 2, (pool, k)


@pytest.mark.parametrize("heldout", HELDOUT_POOLS)
def test_the_pools_are_disjoint(heldout):
    # against the tune pools written before it: a later pool, read after its own report
    # (heldout-16), was written without the earlier held-out pools and may share their words
    before = POOLS[: POOLS.index(heldout)]
    # pools someone here had read when it was written: the held-out pools read after their
    # report count for the pools written after the last of them
    read = set(TUNE_POOLS)
    if POOLS.index(heldout) > max(POOLS.index(p) for p in READ_HELDOUT_POOLS):
        read |= set(READ_HELDOUT_POOLS)
    tune = {bag(v): f"{p}:{k}" for p in before if p in read for k, v in _bank_entries(p).items()}
    shared = sorted(k for k, v in _bank_entries(heldout).items() if bag(v) in tune)
    assert not shared, f"held-out entries equal to a tune phrasing: {shared}"


@pytest.mark.parametrize("heldout", HELDOUT_POOLS)
def test_no_held_out_phrasing_is_a_training_text(trained, heldout):
    assert bag("a dog barking") in trained and bag("a coffee cup") in trained  # it reads them
    hits = sorted(k for k, v in _bank_entries(heldout).items() if bag(v) in trained)
    assert not hits, f"held-out entries equal to a training text: {hits}"


@pytest.mark.parametrize("heldout", HELDOUT_POOLS)
def test_held_out_suite_queries_are_no_training_texts(trained, heldout):
    hits = []
    for tf in _suites(heldout):
        for g in tf.goals:
            texts = [g.instruction] if g.instruction else []
            for lm in [g.query] if g.query else g.landmarks:
                texts += [v for k, v in lm.parts if k != "img"]
            hits += [f"{tf.name}:{g.id}" for t in texts if bag(t) in trained]
    assert not hits, f"held-out goals asking a training text: {hits}"


def test_a_broken_bank_names_the_entry(tmp_path):
    text = (DATA_DIR / "paraphrases" / "tune.toml").read_text()
    p = tmp_path / "tune.toml"
    p.write_text(text.replace('[objects.tray]\nnames = ["{c}', '[objects.tray]\nnamez = ["{c}'))
    with pytest.raises(AssetError, match=r"\[objects.tray\]: unknown keys \['namez'\]"):
        load_bank("tune", p)
    p.write_text(text.replace('"the left end"', '"over on the left"'))
    with pytest.raises(AssetError, match="must be noun phrases starting with 'the '"):
        load_bank("tune", p)
    with pytest.raises(AssetError, match="pool is 'tune', expected 'heldout'"):
        load_bank("heldout", DATA_DIR / "paraphrases" / "tune.toml")
    with pytest.raises(ConfigError, match="unknown paraphrase pool 'test'; valid"):
        load_bank("test")


# ---------------------------------------------------------------------------- generation
def spec_ground_truth(seed: int, sounds: int = 6, repeats: int = 1) -> GroundTruth:
    """The generated scene's ground truth from its spec (no scan), with ``sounds`` synthetic
    sound events of held-out-split categories (the first ``repeats`` heard twice)."""
    spec = SceneRef(random={"seed": seed, "count": 9, "duplicates": 2}).load()
    objs = [
        object_truth(o, 4 + i, o.T_world_obj, o.position, o.yaw_deg, o.aabb())
        for i, o in enumerate(spec.objects)
    ]
    bank = SoundBank.default()
    rng = np.random.default_rng([seed, 99])
    usable = [c for c in bank.categories if bank.clips(category=c, split="heldout")]
    cats = [str(c) for c in rng.choice(usable, sounds - repeats, replace=False)]
    cats += cats[:repeats]
    points = [(0.35, 0.25), (0.35, -0.25), (0.55, 0.3), (0.55, -0.3), (0.65, 0.0), (0.45, 0.0)]
    events = [
        SoundEventTruth(
            episode=f"episode_{i}",
            category=c,
            caption=bank.caption(c),
            clip_id=f"{c}-{i}",
            onset_s=10.0 + 5 * i,
            offset_s=12.0 + 5 * i,
            frames=(0, 1),
            tcp_mean=(*points[i % 6], 0.3),
            table_point=(*points[i % 6], 0.0),
            region_center=(*points[i % 6], 0.0),
        )
        for i, c in enumerate(cats)
    ]
    t = spec.table
    return GroundTruth(
        scene=spec.to_dict(),
        frame="world = robot base frame; table top at z = 0; metres",
        table=TableTruth(x=t.x, y=t.y, top_z=0.0, height=t.height),
        objects=tuple(objs),
        areas=tuple(
            AreaTruth(name=a.name, aliases=a.aliases, x=a.x, y=a.y, center=a.center)
            for a in spec.areas
        ),
        sound_events=tuple(events),
    )


def _doc(pool: str, seed: int, gt_seed: int | None = None) -> dict:
    stem, scene, scan = suite_sections(pool)[0]
    gt = spec_ground_truth(seed if gt_seed is None else gt_seed)
    return paraphrase_suite(pool, stem, scene, scan, gt, seed=seed, bank=BANKS[pool])


@pytest.mark.parametrize("pool", POOLS)
def test_generation_is_seeded_and_deterministic(pool):
    a, b = to_toml(_doc(pool, 31)), to_toml(_doc(pool, 31))
    assert a == b
    assert to_toml(_doc(pool, 32, gt_seed=31)) != a  # another seed words and draws otherwise


def _template(t: str) -> re.Pattern:
    """A bank template as a pattern: each placeholder any words."""
    return re.compile(re.sub(r"\\\{[a-z]\\\}", ".+", re.escape(t)))


@pytest.mark.parametrize("pool", POOLS)
@pytest.mark.parametrize("seed", [31, 33, 35])
def test_generated_goals_are_asked_the_way_people_ask(pool, seed):
    gt = spec_ground_truth(seed)
    doc = _doc(pool, seed)
    types = Counter(g["type"] for g in doc["goals"])
    assert set(types) == set(GOAL_TYPES) and types["absent"] >= MIN_ABSENT, types
    # another word order is a paraphrase ("cube toy"); the label itself is not
    labels = {norm(o.label) for o in gt.objects} | {norm(k.label) for k in OBJECT_KINDS.values()}
    captions = {norm(e.caption) for e in gt.sound_events}
    colour_words = {
        c: {bag(c), *(bag(bare_colour_word(w)) for w in BANKS[pool].colours.get(c, ()))}
        for c in COLORS
    }
    for g in doc["goals"]:
        parts = [g["query"]] if "query" in g else g.get("landmarks", [])
        for p in parts:
            assert norm(str(p.get("obj", ""))) not in labels, g["id"]  # never the catalog label
            assert norm(str(p.get("sound", ""))) not in captions, g["id"]  # nor the caption
        if g["type"] == "object":
            o = gt.object(g["truth"]["object"])
            if len(gt.objects_of_kind(o.kind)) > 1:  # the colour tells the two apart
                words = bag(g["query"]["obj"]).split()

                # a pattern may glue a suffix to the colour ("{c}ish"): "yellowish" says yellow
                def said(cw: str, words=words) -> bool:
                    *lead, last = cw.split()
                    return all(w in words for w in lead) and any(q.startswith(last) for q in words)

                assert any(said(cw) for cw in colour_words[o.color]), g["id"]
        if g["type"] == "instruction":  # one of the bank's templates, filled
            ins = BANKS[pool].instructions
            verbs = [re.escape(v) + " .+" for v in ins["verbs"]]
            forms = [_template(t) for k, ts in ins.items() if k != "verbs" for t in ts]
            forms += [re.compile(v) for v in verbs]
            assert any(f.fullmatch(g["instruction"]) for f in forms), g["id"]
        if g["type"] == "absent":
            assert g["truth"] == {"absent": True} and len(g["query"]) == 1
        # a phrase with its own determiner gets no "the" ("a kiwi fruit", "my car keys")
        assert not re.search(r"\bthe (?:a|an|the|my|your|some) ", g["text"].lower()), g["id"]


def _tune_text() -> str:
    return (DATA_DIR / "paraphrases" / "tune.toml").read_text()


def test_instructions_are_kept_as_the_bank_words_them_even_where_the_reader_refuses(tmp_path):
    from tabletop.language import ParseError, parse_instruction

    text = _tune_text()
    start = text.index("[instructions]\nverbs = [")
    end = text.index("]", start + len("[instructions]\nverbs = ["))
    p = tmp_path / "tune.toml"
    p.write_text(text[:start] + '[instructions]\nverbs = ["zorp blick"' + text[end:])
    bank = load_bank("tune", p)
    stem, scene, scan = suite_sections("tune")[0]
    doc = paraphrase_suite("tune", stem, scene, scan, spec_ground_truth(31), seed=31, bank=bank)
    said = [g["instruction"] for g in doc["goals"] if g["type"] == "instruction"]
    verbed = [t for t in said if t.startswith("zorp blick ")]
    assert verbed, said  # kept, not retried until the reader reads it
    with pytest.raises(ParseError):
        parse_instruction(verbed[0])


def test_absent_goals_include_places_asked_as_areas():
    bank = BANKS["tune"]
    assert bank.absent_areas and all(p.startswith("the ") for p in bank.absent_areas)
    doc = _doc("tune", 31)
    areas = [g for g in doc["goals"] if g["type"] == "absent" and "area" in g["query"]]
    assert len(areas) == 2, [g["id"] for g in doc["goals"] if g["type"] == "absent"]
    for g in areas:
        assert g["id"].startswith("absent-area-") and g["truth"] == {"absent": True}
        assert g["query"]["area"] == g["text"] and g["text"] in bank.absent_areas


def test_a_pool_without_absent_places_loads_and_words_no_absent_area(tmp_path):
    text = _tune_text()
    start = text.index("[absent.areas]")
    end = text.index("[instructions]")
    p = tmp_path / "tune.toml"
    p.write_text(text[:start] + text[end:])
    bank = load_bank("tune", p)
    assert bank.absent_areas == ()
    stem, scene, scan = suite_sections("tune")[0]
    doc = paraphrase_suite("tune", stem, scene, scan, spec_ground_truth(31), seed=31, bank=bank)
    absent = [g for g in doc["goals"] if g["type"] == "absent"]
    assert len(absent) >= MIN_ABSENT and not [g for g in absent if "area" in g["query"]]


def test_a_broken_absent_places_entry_names_it(tmp_path):
    text = _tune_text()
    p = tmp_path / "tune.toml"
    start = text.index("[absent.areas]")
    end = text.index("[instructions]")
    p.write_text(text[:start] + "[absent.areas]\nphrases = []\n\n" + text[end:])
    with pytest.raises(AssetError, match=r"\[absent.areas\].phrases: expected a non-empty list"):
        load_bank("tune", p)
    p.write_text(text[:start] + '[absent.areas]\nplaces = ["the attic"]\n\n' + text[end:])
    with pytest.raises(AssetError, match=r"\[absent.areas\]: unknown keys \['places'\]"):
        load_bank("tune", p)


def test_an_absent_place_the_scene_has_is_refused():
    from tabletop.eval.tasks import Landmark, TaskFileError
    from tabletop.eval.truth import check_absent

    gt = spec_ground_truth(31)
    name = gt.areas[0].name
    with pytest.raises(TaskFileError, match=f"asks area='the {name}', which this recording has"):
        check_absent(Landmark((("area", f"the {name}"),), "area"), gt, "goal 'x'")
    check_absent(Landmark((("area", "the attic"),), "area"), gt, "goal 'x'")  # no error


# ---------------------------------------------------------------------------- shipped suites
def _suites(pool: str):
    d = DATA_DIR / "tasks" / SUITE_DIRS[pool]
    return [load_tasks(p) for p in sorted(d.glob("*.toml"))]


@pytest.mark.parametrize(("pool", "seeds"), list(POOL_SEEDS.items()))
def test_shipped_paraphrase_suites_load_and_cover_every_goal_type(pool, seeds):
    from tabletop.eval.runner import collect_task_files

    files = _suites(pool)
    assert [f.scene.random["seed"] for f in files] == list(seeds)
    assert [f.name for f in collect_task_files(SUITE_DIRS[pool])] == [f.name for f in files]
    seen = set()
    for f in files:
        assert f.extra["generator"]["pool"] == pool and f.scan["seed"] == f.scene.random["seed"]
        types = Counter(g.type for g in f.goals)
        seen |= set(types)
        # a scene whose scan placed no sound the generator can tie to a thing has no
        # multimodal goal (heldout-24's 1052, found after it was judged: kept as judged)
        assert set(GOAL_TYPES) - {"multimodal_spatial"} <= set(types) <= set(GOAL_TYPES), (
            f.name,
            types,
        )
        assert types["absent"] >= MIN_ABSENT, f.name
        # object truths resolve against the scene (sounds need the scan: the runner checks)
        gt = spec_ground_truth(f.scene.random["seed"], sounds=0, repeats=0)
        for g in f.goals:
            if g.truth.kind == "object":
                resolve_truth(g.truth, gt, f"{f.name} {g.id}")
    assert seen == set(GOAL_TYPES), pool  # the pool as a whole asks every type


def test_paraphrase_seeds_are_used_nowhere_else():
    from tabletop.eval.calibration import CALIBRATION_SEEDS
    from tabletop.eval.suites import DEFAULT_SUITES
    from tabletop.train.vision import EVAL_SEED_BASE, VisionTrainConfig

    ours = {s for seeds in POOL_SEEDS.values() for s in seeds}
    assert len(ours) == sum(len(seeds) for seeds in POOL_SEEDS.values())  # no two pools share
    shipped = {s["random"]["seed"] for _, s, _ in DEFAULT_SUITES if "random" in s}
    scans = {scan["seed"] for _, _, scan in DEFAULT_SUITES}
    cfg = VisionTrainConfig()
    vision = set(range(cfg.seed * 100_000, cfg.seed * 100_000 + cfg.train_layouts))
    assert not ours & (shipped | scans | set(CALIBRATION_SEEDS) | vision)
    assert min(ours) < EVAL_SEED_BASE
    assert not ours & set(range(10, 10 + 100))  # eval-map's generated scenes: seed + 10


def test_a_filled_template_never_doubles_a_determiner():
    from tabletop.eval.paraphrase import _fill, _one_determiner

    # the generator gives each thing its "the" unless the template or the name has one
    assert _fill("go between {a} and the {b}", a="mug", b="duck") == (
        "go between the mug and the duck"
    )
    assert _fill("left of {a}", a="my cup") == "left of my cup"
    # a pattern's "the" meeting a colour word with its own determiner keeps one
    assert _one_determiner("the the colour of grass one") == "the colour of grass one"
    assert _one_determiner("the mug that is the blue one") == "the mug that is the blue one"
