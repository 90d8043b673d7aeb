"""Hardening of image paths in generated code: ``load_image`` and ``img=`` read only inside the
image directory, and a refusal reads the same whether or not the file exists."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from test_hardening_sandbox import PointRobot

from tabletop.errors import ConfigError
from tabletop.language import run_code
from tabletop.language.run import TracingRobot


@pytest.fixture
def image_dir(tmp_path):
    images = tmp_path / "images"
    images.mkdir()
    cv2.imwrite(str(images / "goal.png"), np.full((8, 8, 3), 200, np.uint8))
    cv2.imwrite(str(tmp_path / "secret.png"), np.zeros((8, 8, 3), np.uint8))
    (images / "link.png").symlink_to(tmp_path / "secret.png")
    return images


@pytest.mark.parametrize(
    "path",
    [
        "../secret.png",  # exists, outside
        "link.png",  # a link inside that leads outside
        "/etc/passwd",
        "/no/such/file.png",  # must read exactly as one that exists
        "{secret}",
        "images/../../secret.png",
    ],
)
def test_image_paths_in_code_are_confined_to_the_image_directory(image_dir, path):
    path = path.format(secret=image_dir.parent / "secret.png")
    for code in (f"img = robot.load_image({path!r})", f"h = robot.get_major_map(img={path!r})"):
        robot = PointRobot()
        with pytest.raises(ConfigError) as e:
            run_code(code, TracingRobot(robot, image_dir=image_dir))
        how = " through a link" if path == "link.png" else ""  # where it leads stays unsaid
        assert str(e.value) == (
            f"image path {path!r} leads outside the image directory {str(image_dir)!r}{how}; "
            "give a path inside it (relative paths are read from it)"
        )
        assert robot.images == []


def test_an_image_inside_the_directory_is_read(image_dir):
    robot = PointRobot()
    tracer = TracingRobot(robot, image_dir=image_dir)
    code = "a = robot.load_image('goal.png')\nh = robot.get_major_map(img='goal.png')\n"
    run = run_code(code, tracer)
    assert robot.images == [image_dir / "goal.png"] * 2
    assert run.calls[1].result.shape == (8, 8, 3) and run.calls[1].result[0, 0, 0] == 200
    with pytest.raises(ConfigError, match="does not exist"):
        run_code("a = robot.load_image('missing.png')", tracer)
