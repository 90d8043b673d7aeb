"""The readers' cost (``tabletop bench``): milliseconds per request, one thread, and the words
still listed by hand in code.

The requests are the project's own ("go to ...", relations, sounds, typing slips), not an
evaluation pool's. Each reader reads each request once to warm up (models load), then
``repeats`` times; the median and 95th percentile per request are reported.
"""

from __future__ import annotations

import ast
import re
import time
from pathlib import Path

import numpy as np

from tabletop.reader.errors import ParseError
from tabletop.reader.reading import READERS, get_reader

__all__ = ["BENCH_PLACES", "BENCH_REQUESTS", "listed_words", "run_reader_benchmark"]

BENCH_REQUESTS = (
    "go to the red mug",
    "please move between the tray and the teddy bear",
    "go to the left of the blue lego brick, then to the duck",
    "head to the mug near the sound of a dog barking",
    "could you go where you heard the phone ringing",
    "move 5 cm north",
    "reach the yelow duk",
    "would you be so kind as to hover over the green cube",
    "go back and forth between the ball and the domino twice",
    "gotothe jenga block",
)
#: Area phrases for the place reader's cost: the grammar reads the first two, the classifier
#: the next two, the last is a place off the table (the project's own wording).
BENCH_PLACES = (
    "the left side of the table",
    "the far right corner",
    "the leftward zone of the table",
    "the rightward bit",
    "the garage",
)


def listed_words(path: str | Path) -> int:
    """Distinct lower-case words inside the string literals of a Python file, or of every
    Python file of a package (a folder), docstrings left out: how many words its authors
    listed by hand."""
    path = Path(path)
    files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
    words: set[str] = set()
    for f in files:
        tree = ast.parse(f.read_text(encoding="utf-8"))
        docs = set()
        for node in ast.walk(tree):
            body = getattr(node, "body", None)
            if isinstance(body, list) and body and isinstance(body[0], ast.Expr):
                if isinstance(getattr(body[0], "value", None), ast.Constant):
                    docs.add(id(body[0].value))
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Constant)
                and isinstance(node.value, str)
                and id(node) not in docs
            ):
                words.update(re.findall(r"[a-z]{2,}", node.value.lower()))
    return len(words)


def run_reader_benchmark(repeats: int = 5) -> dict:
    """Per reader: median and p95 milliseconds per request, and how many it refused."""
    import torch

    out: dict = {}
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        for name in (n for n in READERS if n != "llm"):  # llm: no endpoint in a benchmark
            reader = get_reader(name)
            refused = 0
            for text in BENCH_REQUESTS:  # warm-up: spelling tables, MiniLM, the tagger
                try:
                    reader.understand(text)
                except ParseError:
                    refused += 1
            times = []
            for _ in range(repeats):
                for text in BENCH_REQUESTS:
                    t0 = time.perf_counter()
                    try:
                        reader.understand(text)
                    except ParseError:
                        pass
                    times.append((time.perf_counter() - t0) * 1e3)
            key = name.replace("+", "_")
            out[f"reader_{key}_ms_median"] = round(float(np.median(times)), 3)
            out[f"reader_{key}_ms_p95"] = round(float(np.percentile(times, 95)), 3)
            out[f"reader_{key}_refused"] = f"{refused}/{len(BENCH_REQUESTS)}"
        from tabletop.reader.places import PlaceReader, text_encoder

        places = PlaceReader(learned=True)
        for text in BENCH_PLACES:  # warm-up: MiniLM, the classifier
            places.read(text)
        times = []
        for _ in range(repeats):
            for text in BENCH_PLACES:
                text_encoder().clear_cache()  # every phrase embedded afresh
                t0 = time.perf_counter()
                places.read(text)
                times.append((time.perf_counter() - t0) * 1e3)
        out["reader_places_ms_median"] = round(float(np.median(times)), 3)
        out["reader_places_ms_p95"] = round(float(np.percentile(times, 95)), 3)
    finally:
        torch.set_num_threads(threads)
    root = Path(__file__).resolve().parent.parent
    for rel in (
        "reader/rules.py",
        "reader/place_words.py",
        "reader/lexicon/colour_words.py",
        "reader/lexicon",  # the whole lexicon: every word list the map and the robot read with
    ):
        out[f"listed_words_{Path(rel).stem}"] = listed_words(root / rel)
    return out
