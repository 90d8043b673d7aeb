"""Write tabletop/data/colours/names.toml: the one-word colour names of the npm package
color-name-list (MIT, David Aerne and contributors) that the xkcd survey lacks.

    npm pack color-name-list@14.51.0 && tar xzf color-name-list-14.51.0.tgz
    python tools/build_colour_names.py package/dist/colornames.json

The object module reads these only to say *which* colour a word means once the query's own
words (or the text encoder) have said it is a colour ("a quince-coloured cube"); whether a word
is a colour is never decided by this list, which also names everyday things ("bear", "tea").
"""

import json
import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "tabletop" / "data" / "colours" / "names.toml"
VERSION = "14.51.0"


def main(source: str) -> None:
    names = json.loads(Path(source).read_text())
    survey = tomllib.loads((OUT.parent / "survey.toml").read_text())["names"]
    one: dict[str, str] = {}
    for entry in names:
        name, hexa = entry["name"].lower(), entry["hex"].lower()
        if re.fullmatch(r"[a-z]+", name) and re.fullmatch(r"#[0-9a-f]{6}", hexa):
            one.setdefault(name, hexa)
    lines = [
        "# One-word colour names and the sRGB colour each names, from the npm package",
        f"# color-name-list {VERSION} (https://github.com/meodai/color-name-list), MIT licence,",
        "# copyright (c) 2017 David Aerne (its LICENSE is kept beside this file as",
        "# names.LICENSE). Names the xkcd survey (survey.toml) holds are left out.",
        "# Written by tools/build_colour_names.py; read by tabletop/reader/lexicon/colour_words.py",
        "# only to say which colour a word already read as a colour means.",
        "",
        'format = "tabletop-colour-names"',
        "version = 1",
        f'source = "color-name-list {VERSION}, https://github.com/meodai/color-name-list"',
        'licence = "MIT"',
        "",
        "[names]",
    ]
    lines += [f'"{n}" = "{h}"' for n, h in sorted(one.items()) if n not in survey]
    OUT.write_text("\n".join(lines) + "\n")
    print(f"{OUT}: {len(lines) - 13} names")


if __name__ == "__main__":
    main(sys.argv[1])
