"""Write the frames the int8 dense-encoder graph is calibrated on
(tabletop/data/weights/lseg_int8_calibration.npz): renders of vision-training layouts
(tabletop.mapping.encoders.lseg_onnx.CALIBRATION_LAYOUTS, two views each, never a held-out
layout). The map layer reads the file; rendering needs the simulator, which it may not import.

    python tools/build_int8_calibration.py
"""

import numpy as np

from tabletop.mapping.encoders.lseg_onnx import CALIBRATION_LAYOUTS, CALIBRATION_PATH
from tabletop.train.vision import render_dataset


def main() -> None:
    rgbs, _ = render_dataset(list(CALIBRATION_LAYOUTS), views=2, heldout=False, seed=0, lit=True)
    rgbs = np.ascontiguousarray(np.asarray(rgbs, np.uint8))
    np.savez_compressed(CALIBRATION_PATH, rgb=rgbs, layouts=np.array(CALIBRATION_LAYOUTS))
    print(f"{CALIBRATION_PATH}: {rgbs.shape}")


if __name__ == "__main__":
    main()
