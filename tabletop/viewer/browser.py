"""A real browser for the viewer's tests and its time-to-first-picture figure: headless
Chromium (Debian's ``chromium`` and ``chromium-driver``) driven through selenium, drawing WebGL
in software (SwiftShader) where there is no GPU.

:func:`browser_problem` says, in words, why no browser can be had here (no selenium, no
chromium or chromedriver on the path); tests skip with that reason and the benchmark reports
it.
"""

from __future__ import annotations

import io
import os
import shutil
import time
from collections.abc import Callable

import numpy as np

__all__ = [
    "HeadlessBrowser",
    "browser_problem",
    "colour_share",
    "find_browser",
    "first_picture",
    "map_palette",
]

#: Names of the browser and its driver on the path (Debian's packages, then others').
CHROMIUM = ("chromium", "chromium-browser", "google-chrome")
DRIVER = ("chromedriver",)


def find_browser() -> tuple[str | None, str | None]:
    """(chromium, chromedriver) paths found on the path (``TABLETOP_CHROMIUM`` and
    ``TABLETOP_CHROMEDRIVER`` override them); None for one that is missing."""
    browser = os.environ.get("TABLETOP_CHROMIUM") or next(
        (p for n in CHROMIUM if (p := shutil.which(n))), None
    )
    driver = os.environ.get("TABLETOP_CHROMEDRIVER") or next(
        (p for n in DRIVER if (p := shutil.which(n))), None
    )
    return browser, driver


def browser_problem() -> str | None:
    """Why a headless browser cannot be had here (None: it can)."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[dev]')"
    browser, driver = find_browser()
    missing = [n for n, p in (("chromium", browser), ("chromedriver", driver)) if p is None]
    if missing:
        return (
            f"{' and '.join(missing)} not found on the path (Debian: apt-get install -y "
            "--no-install-recommends chromium chromium-driver)"
        )
    return None


class HeadlessBrowser:
    """Headless Chromium of ``size`` (width, height) px, WebGL in software.

    Raises:
        RuntimeError: the browser could not be started (the message says why).
    """

    def __init__(self, size: tuple[int, int] = (1280, 800)) -> None:
        from selenium import webdriver
        from selenium.common.exceptions import WebDriverException
        from selenium.webdriver.chrome.options import Options
        from selenium.webdriver.chrome.service import Service

        problem = browser_problem()
        if problem:
            raise RuntimeError(problem)
        browser, driver = find_browser()
        opts = Options()
        opts.binary_location = browser
        for a in (
            "--headless=new",
            "--no-sandbox",  # CI runs as root
            "--disable-dev-shm-usage",
            f"--window-size={size[0]},{size[1]}",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",  # WebGL without a GPU
            "--autoplay-policy=no-user-gesture-required",
            "--mute-audio",
        ):
            opts.add_argument(a)
        try:
            self.driver = webdriver.Chrome(service=Service(driver), options=opts)
        except WebDriverException as e:
            raise RuntimeError(f"headless chromium did not start: {e.msg or e}") from None
        self.driver.set_page_load_timeout(60)

    def get(self, url: str) -> None:
        self.driver.get(url)

    def screenshot(self) -> np.ndarray:
        """(H, W, 3) uint8 RGB of the page as drawn now."""
        import cv2

        png = self.driver.get_screenshot_as_png()
        bgr = cv2.imdecode(np.frombuffer(io.BytesIO(png).getvalue(), np.uint8), cv2.IMREAD_COLOR)
        return np.ascontiguousarray(bgr[:, :, ::-1])

    def canvas_box(self) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1) px of the 3D scene left of the control panel (its drawn area)."""
        js = """
        const c = document.querySelector('canvas');
        const r = c ? c.getBoundingClientRect() : {left: 0, top: 0, right: innerWidth,
                                                    bottom: innerHeight};
        let right = r.right;
        for (const b of document.querySelectorAll('button')) {
          if (b.innerText.trim() === 'Ask') { right = Math.min(right,
              b.closest('.mantine-Paper-root')?.getBoundingClientRect().left ?? right); }
        }
        return [r.left, r.top, right, r.bottom];"""
        x0, y0, x1, y1 = self.driver.execute_script(js)
        return int(x0), int(y0), int(x1), int(y1)

    def scene(self) -> np.ndarray:
        """The screenshot cropped to :meth:`canvas_box`."""
        x0, y0, x1, y1 = self.canvas_box()
        return self.screenshot()[max(y0, 0) : y1, max(x0, 0) : x1]

    def input_of(self, label: str):
        """The text input of the viewer's field called ``label``."""
        from selenium.webdriver.common.by import By

        return self.driver.find_element(
            By.XPATH,
            f"//label[normalize-space()='{label}']/ancestor::div[contains(@class,"
            "'mantine-Flex-root')][1]//input",
        )

    def button(self, text: str):
        from selenium.webdriver.common.by import By

        return self.driver.find_element(By.XPATH, f"//button[normalize-space()='{text}']")

    def type_into(self, label: str, text: str) -> None:
        from selenium.webdriver.common.keys import Keys

        box = self.input_of(label)
        box.click()
        box.send_keys(Keys.CONTROL, "a")
        box.send_keys(Keys.DELETE)
        box.send_keys(text)

    def wait_enabled(self, text: str, timeout: float = 60.0) -> None:
        """Wait until the button ``text`` can be clicked."""
        wait_for(lambda: self.button(text).is_enabled(), timeout, f"button {text!r} enabled")

    def close(self) -> None:
        try:
            self.driver.quit()
        except Exception:  # already gone
            pass

    def __enter__(self) -> HeadlessBrowser:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def wait_for(pred: Callable[[], object], timeout: float, what: str, every: float = 0.1):
    """``pred()``'s first truthy value within ``timeout`` s (TimeoutError naming ``what``)."""
    end = time.monotonic() + timeout
    while True:
        try:
            v = pred()
        except Exception:  # a page element not there yet
            v = None
        if v:
            return v
        if time.monotonic() > end:
            raise TimeoutError(f"{what}: not within {timeout:g} s")
        time.sleep(every)


def map_palette(colours: np.ndarray, min_share: float = 0.002, bits: int = 4) -> np.ndarray:
    """The colour bins (``bits`` per channel, as ints) that hold at least ``min_share`` of a
    map's voxel colours, leaving out near-white and near-grey bins (the page's own colours):
    what a screenshot of the map must show."""
    c = np.asarray(colours, np.int64).reshape(-1, 3) >> (8 - bits)
    key = (c[:, 0] << (2 * bits)) | (c[:, 1] << bits) | c[:, 2]
    k, n = np.unique(key, return_counts=True)
    k = k[n >= max(1, min_share * len(key))]
    mask = (1 << bits) - 1
    rgb = np.stack([(k >> (2 * bits)) & mask, (k >> bits) & mask, k & mask], 1)
    spread = rgb.max(1) - rgb.min(1)
    return k[spread >= 2]  # the page is white and greys; the map's colours are not all grey


def colour_share(img: np.ndarray, palette: np.ndarray, bits: int = 4) -> float:
    """Share of ``img``'s pixels whose colour bin is in ``palette`` (:func:`map_palette`)."""
    c = np.asarray(img, np.int64).reshape(-1, 3) >> (8 - bits)
    key = (c[:, 0] << (2 * bits)) | (c[:, 1] << bits) | c[:, 2]
    return float(np.isin(key, palette).mean()) if len(key) else 0.0


def first_picture(
    browser: HeadlessBrowser, url: str, palette: np.ndarray, share: float = 0.01,
    timeout: float = 60.0,
) -> float:  # fmt: skip
    """Open ``url`` and wait until the scene shows the map's colours (at least ``share`` of
    its pixels in ``palette``); the seconds it took from the request."""
    t0 = time.perf_counter()
    browser.get(url)
    wait_for(lambda: colour_share(browser.scene(), palette) >= share, timeout, "the map drawn",
             every=0.05)  # fmt: skip
    return time.perf_counter() - t0
