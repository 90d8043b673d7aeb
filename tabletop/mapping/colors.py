"""Perceptual colour: how far two colours look apart.

The object module composes a colour word of a query ("the crimson mug") with the colour an
object instance was measured to have (the mean RGB of its fused pixels), because the learned
image embedding alone does not carry colour reliably for colour–kind pairs it never saw. The
comparison goes through the text encoder, so it is not a lookup of the simulator's colours: a
measured colour is compared with the colour lexicon's names
(:data:`~tabletop.reader.lexicon.colour_names.COLOR_NAMES`, each with a typical sRGB value) by
the perceptual distance ΔE in CIELAB (:func:`rgb_to_lab`).

The words live in the lexicon (:mod:`tabletop.reader.lexicon`): the colour names in
:mod:`~tabletop.reader.lexicon.colour_names`, which words of a query are colour words in
:mod:`~tabletop.reader.lexicon.colour_words`.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "delta_e",
    "delta_e94",
    "rgb_to_lab",
    "shaded_lab",
]


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
