"""Colour names and perceptual colour: what a person calls a colour, and how far two colours
look apart.

The object module composes a colour word of a query ("the crimson mug") with the colour an
object instance was measured to have (the mean RGB of its fused pixels), because the learned
image embedding alone does not carry colour reliably for colour–kind pairs it never saw. The
comparison goes through the text encoder, so it is not a lookup of the simulator's colours:

- :data:`COLOR_NAMES` is a lexicon of everyday English colour names with a typical sRGB value
  each (web and paint-chart conventions) and the basic colour term it is a shade of; a
  measured colour is compared with them by the perceptual distance ΔE in CIELAB
  (:func:`rgb_to_lab`).
- A query's colour word is embedded by the text encoder and compared with the embeddings of
  those names; any word the text encoder places near a lexicon name scores — "scarlet" near
  "red", "navy" near "dark blue" — not only the lexicon's own names.

:mod:`tabletop.mapping.colour_words` says which words of a query are colour words.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "BASIC_COLOURS",
    "COLOR_MODIFIERS",
    "COLOR_NAMES",
    "delta_e",
    "delta_e94",
    "rgb_to_lab",
    "shaded_lab",
]

#: The basic colour terms of English: every lexicon name belongs to one of them.
BASIC_COLOURS = (
    "black",
    "white",
    "red",
    "green",
    "yellow",
    "blue",
    "brown",
    "purple",
    "pink",
    "orange",
    "grey",
)

#: Everyday colour names -> (a typical sRGB value (0-255), the basic colour term it is a shade
#: of: "scarlet" is a red, "navy" a blue).
COLOR_NAMES: dict[str, tuple[tuple[int, int, int], str]] = {
    "red": ((220, 30, 30), "red"),
    "dark red": ((139, 0, 0), "red"),
    "crimson": ((220, 20, 60), "red"),
    "scarlet": ((255, 36, 0), "red"),
    "maroon": ((128, 0, 0), "red"),
    "burgundy": ((128, 0, 32), "red"),
    "pink": ((255, 150, 180), "pink"),
    "hot pink": ((255, 105, 180), "pink"),
    "rose": ((255, 0, 127), "pink"),
    "magenta": ((255, 0, 255), "purple"),
    "orange": ((255, 140, 0), "orange"),
    "coral": ((255, 127, 80), "orange"),
    "salmon": ((250, 128, 114), "pink"),
    "peach": ((255, 203, 164), "orange"),
    "yellow": ((255, 225, 25), "yellow"),
    "gold": ((255, 200, 0), "yellow"),
    "lemon": ((255, 247, 0), "yellow"),
    "mustard": ((225, 173, 1), "yellow"),
    "amber": ((255, 191, 0), "orange"),
    "cream": ((255, 253, 208), "white"),
    "beige": ((225, 210, 170), "brown"),
    "tan": ((210, 180, 140), "brown"),
    "khaki": ((195, 176, 145), "brown"),
    "brown": ((130, 80, 40), "brown"),
    "dark brown": ((92, 64, 51), "brown"),
    "chocolate": ((123, 63, 0), "brown"),
    "caramel": ((175, 111, 9), "brown"),
    "bronze": ((205, 127, 50), "brown"),
    "green": ((40, 160, 50), "green"),
    "dark green": ((0, 100, 0), "green"),
    "lime": ((150, 230, 40), "green"),
    "olive": ((128, 128, 0), "green"),
    "mint": ((152, 255, 152), "green"),
    "emerald": ((80, 200, 120), "green"),
    "teal": ((0, 128, 128), "blue"),
    "turquoise": ((64, 224, 208), "blue"),
    "cyan": ((0, 220, 230), "blue"),
    "blue": ((30, 80, 220), "blue"),
    "light blue": ((150, 200, 240), "blue"),
    "sky blue": ((135, 206, 235), "blue"),
    "navy": ((0, 0, 128), "blue"),
    "dark blue": ((0, 30, 120), "blue"),
    "royal blue": ((65, 105, 225), "blue"),
    "cobalt": ((0, 71, 171), "blue"),
    "indigo": ((75, 0, 130), "purple"),
    "purple": ((128, 40, 170), "purple"),
    "violet": ((143, 0, 255), "purple"),
    "lavender": ((200, 170, 230), "purple"),
    "lilac": ((200, 162, 200), "purple"),
    "plum": ((142, 69, 133), "purple"),
    "white": ((245, 245, 245), "white"),
    "ivory": ((255, 255, 240), "white"),
    "off-white": ((240, 236, 225), "white"),
    "silver": ((192, 192, 192), "grey"),
    "light grey": ((200, 200, 200), "grey"),
    "grey": ((128, 128, 128), "grey"),
    "gray": ((128, 128, 128), "grey"),
    "dark grey": ((80, 80, 80), "grey"),
    "charcoal": ((54, 69, 79), "grey"),
    # Names people reach for beside the basic ones (gems, fruit, paint charts), which the text
    # encoder alone places poorly (a lone "mauve" lands nearer "rose" than "purple"). Not
    # words that name a material or a thing a mug or a block is often called by ("coffee",
    # "steel", "copper", "brick", "ash", "wine"): those stay part of the thing's description.
    # None is a phrasing of the held-out paraphrase pool (tests/test_paraphrase.py).
    "garnet": ((115, 54, 53), "red"),
    "vermilion": ((227, 66, 52), "red"),
    "carmine": ((150, 0, 24), "red"),
    "cardinal": ((196, 30, 58), "red"),
    "cherry red": ((210, 4, 45), "red"),
    "brick red": ((203, 65, 84), "red"),
    "blood red": ((136, 8, 8), "red"),
    "wine red": ((114, 47, 55), "red"),
    "fuchsia": ((255, 0, 200), "pink"),
    "cerise": ((222, 49, 99), "pink"),
    "blush": ((222, 93, 131), "pink"),
    "raspberry": ((227, 11, 92), "pink"),
    "baby pink": ((244, 194, 194), "pink"),
    "flamingo pink": ((252, 142, 172), "pink"),
    "tangerine": ((242, 133, 0), "orange"),
    "pumpkin": ((255, 117, 24), "orange"),
    "apricot": ((251, 206, 177), "orange"),
    "marigold": ((234, 162, 33), "orange"),
    "terracotta": ((226, 114, 91), "orange"),
    "burnt orange": ((204, 85, 0), "orange"),
    "canary": ((255, 239, 0), "yellow"),
    "saffron": ((244, 196, 48), "yellow"),
    "daffodil": ((255, 255, 49), "yellow"),
    "golden": ((255, 200, 0), "yellow"),
    "sunflower yellow": ((255, 218, 3), "yellow"),
    "banana yellow": ((255, 225, 53), "yellow"),
    "sage": ((178, 172, 136), "green"),
    "chartreuse": ((127, 255, 0), "green"),
    "pistachio": ((147, 197, 114), "green"),
    "moss": ((138, 154, 91), "green"),
    "avocado": ((86, 130, 3), "green"),
    "fern": ((79, 121, 66), "green"),
    "shamrock": ((0, 158, 96), "green"),
    "viridian": ((64, 130, 109), "green"),
    "malachite": ((11, 218, 81), "green"),
    "kelly green": ((76, 187, 23), "green"),
    "bottle green": ((0, 106, 78), "green"),
    "sea green": ((46, 139, 87), "green"),
    "army green": ((75, 83, 32), "green"),
    "azure": ((0, 127, 255), "blue"),
    "cerulean": ((0, 123, 167), "blue"),
    "ultramarine": ((18, 10, 143), "blue"),
    "denim": ((21, 96, 189), "blue"),
    "cornflower": ((100, 149, 237), "blue"),
    "aqua": ((0, 255, 255), "blue"),
    "aquamarine": ((127, 255, 212), "blue"),
    "baby blue": ((137, 207, 240), "blue"),
    "powder blue": ((176, 224, 230), "blue"),
    "steel blue": ((70, 130, 180), "blue"),
    "midnight blue": ((25, 25, 112), "blue"),
    "electric blue": ((125, 249, 255), "blue"),
    "navy blue": ((0, 0, 128), "blue"),
    "mauve": ((224, 176, 255), "purple"),
    "eggplant": ((97, 64, 81), "purple"),
    "amethyst": ((153, 102, 204), "purple"),
    "grape": ((111, 45, 168), "purple"),
    "orchid": ((218, 112, 214), "purple"),
    "mulberry": ((197, 75, 140), "purple"),
    "wisteria": ((201, 160, 220), "purple"),
    "periwinkle": ((204, 204, 255), "purple"),
    "mahogany": ((192, 64, 0), "brown"),
    "mocha": ((120, 85, 60), "brown"),
    "sepia": ((112, 66, 20), "brown"),
    "cinnamon": ((210, 105, 30), "brown"),
    "cocoa": ((135, 95, 66), "brown"),
    "umber": ((99, 81, 71), "brown"),
    "sienna": ((160, 82, 45), "brown"),
    "taupe": ((72, 60, 50), "brown"),
    "camel": ((193, 154, 107), "brown"),
    "toffee": ((117, 76, 36), "brown"),
    "russet": ((128, 70, 27), "brown"),
    "auburn": ((165, 42, 42), "brown"),
    "fawn": ((229, 170, 112), "brown"),
    "pearl": ((234, 224, 200), "white"),
    "alabaster": ((237, 234, 224), "white"),
    "eggshell": ((240, 234, 214), "white"),
    "linen": ((250, 240, 230), "white"),
    "snow white": ((255, 250, 250), "white"),
    "slate": ((112, 128, 144), "grey"),
    "graphite": ((56, 60, 63), "grey"),
    "gunmetal": ((42, 52, 57), "grey"),
    "platinum": ((229, 228, 226), "grey"),
    "ash grey": ((178, 190, 181), "grey"),
    "steel grey": ((113, 121, 126), "grey"),
    "onyx": ((53, 56, 57), "black"),
    "obsidian": ((30, 30, 35), "black"),
    "jet black": ((52, 52, 52), "black"),
    "pitch black": ((10, 10, 10), "black"),
    "black": ((15, 15, 15), "black"),
}

#: Words that modify a colour ("dark blue", "pale pink"); part of a colour phrase, not a noun.
COLOR_MODIFIERS = ("light", "dark", "pale", "bright", "deep", "vivid", "pastel", "soft")


def delta_e(a, b) -> np.ndarray:
    """CIELAB distance between colours (..., 3), lightness at half weight: shading changes
    it across one object, and a colour's name depends more on its hue and chroma."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    return np.sqrt((0.5 * d[..., 0]) ** 2 + d[..., 1] ** 2 + d[..., 2] ** 2)


def delta_e94(a, b) -> np.ndarray:
    """CIE94 distance from colours ``a`` (..., 3) to reference colours ``b`` (..., 3), both
    CIELAB, lightness at half weight: differences of chroma and hue count less where ``a`` is
    more saturated. Which name's family a pale tint belongs to: butter (a pale yellow) is
    nearer olive than any yellow by :func:`delta_e`, nearer a yellow by this."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    d_l = a[..., 0] - b[..., 0]
    c_a = np.hypot(a[..., 1], a[..., 2])
    d_c = c_a - np.hypot(b[..., 1], b[..., 2])
    d_h2 = np.maximum((a[..., 1] - b[..., 1]) ** 2 + (a[..., 2] - b[..., 2]) ** 2 - d_c**2, 0.0)
    return np.sqrt(
        (0.5 * d_l) ** 2 + (d_c / (1 + 0.045 * c_a)) ** 2 + d_h2 / (1 + 0.015 * c_a) ** 2
    )


def shaded_lab(rgb, gains) -> np.ndarray:
    """CIELAB (len(gains), ..., 3) of sRGB colours (..., 3) in 0-255 lit at each gain (a factor
    on linear light, 1 = as named): how a colour looks on a face the light reaches less."""
    c = np.asarray(rgb, dtype=np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    out = []
    for g in np.asarray(gains, dtype=np.float64).reshape(-1):
        x = np.clip(lin * g, 0.0, 1.0)
        srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
        out.append(rgb_to_lab(255.0 * srgb))
    return np.stack(out)


def rgb_to_lab(rgb) -> np.ndarray:
    """CIELAB (D65) of sRGB colours (..., 3) in 0-255 (float): L in [0, 100]."""
    c = np.asarray(rgb, dtype=np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    m = np.array(
        [
            [0.4124564, 0.3575761, 0.1804375],
            [0.2126729, 0.7151522, 0.0721750],
            [0.0193339, 0.1191920, 0.9503041],
        ]
    )
    xyz = lin @ m.T / np.array([0.95047, 1.0, 1.08883])
    e = 216 / 24389
    f = np.where(xyz > e, np.cbrt(xyz), (24389 / 27 * xyz + 16) / 116)
    L = 116 * f[..., 1] - 16
    a = 500 * (f[..., 0] - f[..., 1])
    b = 200 * (f[..., 1] - f[..., 2])
    return np.stack([L, a, b], axis=-1)
