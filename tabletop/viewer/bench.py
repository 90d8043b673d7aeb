"""The viewer's time to first picture, measured with a real browser.

:func:`time_to_first_picture` starts ``tabletop view MAP`` as a person would (a new process),
opens its address in headless Chromium that is already running (a person's browser is), and
waits until the page's 3D scene shows the map's colours: the seconds from the command's start
to that picture, and how they split between the command serving the page and the page drawing
it. WebGL runs in software in a machine without a GPU, as here.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

__all__ = ["time_to_first_picture"]


def time_to_first_picture(map_path, timeout: float = 120.0) -> dict:
    """The viewer's time to first picture of the map at ``map_path``, twice in one browser:
    the first opening (``viewer_first_picture_s``: nothing of the page cached, as when a person
    opens the viewer the first time) and the second (``viewer_first_picture_warm_s``: the
    browser has the page's scripts cached); each split into ``served`` (the command's start to
    its address printed) and ``drawn`` (the page asked for to the map drawn). With
    ``viewer_voxels``, ``viewer_voxel_size_m`` and ``viewer_browser``; {"viewer_skipped": why}
    where the viewer extra or a headless browser cannot be had."""
    from tabletop.mapping.persistence import read_map_preview
    from tabletop.viewer.browser import HeadlessBrowser, browser_problem, map_palette

    try:
        import viser  # noqa: F401
    except ImportError:
        return {"viewer_skipped": "the viewer extra is not installed (pip install -e '.[viewer]')"}
    problem = browser_problem()
    if problem:
        return {"viewer_skipped": problem}
    preview = read_map_preview(map_path)
    palette = map_palette(preview.colors)
    try:
        browser = HeadlessBrowser()
    except RuntimeError as e:
        return {"viewer_skipped": str(e)}
    out = {}
    try:
        browser.get("about:blank")
        version = browser.driver.capabilities.get("browserVersion", "?")
        for suffix in ("", "_warm"):
            t = _one_opening(browser, map_path, palette, timeout)
            if isinstance(t, str):
                return {"viewer_skipped": t}
            total, served, drawn = t
            out[f"viewer_first_picture{suffix}_s"] = round(total, 2)
            out[f"viewer_served{suffix}_s"] = round(served, 2)
            out[f"viewer_drawn{suffix}_s"] = round(drawn, 2)
            browser.get("about:blank")
    finally:
        browser.close()
    return {
        **out,
        "viewer_voxels": len(preview.centers),
        "viewer_voxel_size_m": preview.grid.voxel_size,
        "viewer_browser": f"headless chromium {version}, software WebGL",
    }


def _one_opening(browser, map_path, palette, timeout: float):
    """(total, served, drawn) [s] of one ``tabletop view MAP`` opened in ``browser``, or why
    it could not be measured."""
    from tabletop.viewer.app import _free_port
    from tabletop.viewer.browser import first_picture

    port = _free_port("127.0.0.1")
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    cmd = [sys.executable, "-m", "tabletop.cli", "view", str(Path(map_path))]
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [*cmd, "--port", str(port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env=env,
    )
    try:
        url = None
        while url is None:
            line = proc.stdout.readline()
            if not line:
                return f"tabletop view exited ({proc.wait()}) before serving"
            if line.startswith("open http"):
                url = line.split()[1]
            if time.perf_counter() - t0 > timeout:
                return "tabletop view did not serve within the time limit"
        served = time.perf_counter() - t0
        drawn = first_picture(browser, url, palette, timeout=timeout)
        return time.perf_counter() - t0, served, drawn
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
