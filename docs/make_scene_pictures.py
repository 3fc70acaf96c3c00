"""Render one picture per built-in scene: a ground-truth sub-frame beside a coded frame (4×4).

Run: ``python docs/make_scene_pictures.py [--out FOLDER]`` (writes docs/scenes/*.png by default).
"""

import argparse
from pathlib import Path

import cv2
import numpy as np

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.simulate.scenes import SCENES, render_scene


def main(out: Path = Path(__file__).parent / "scenes") -> None:
    out.mkdir(parents=True, exist_ok=True)
    code = design_code((4, 4)).code
    for name in SCENES:
        video = render_scene(name, 32, 120, 160, seed=0)
        frame = capture(video, code)[1]
        panel = np.concatenate([video[16 + 8], np.ones((120, 4), np.float32), frame], axis=1)
        img = cv2.resize((panel * 255).astype(np.uint8), None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
        cv2.imwrite(str(out / f"{name}.png"), img)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "scenes", help="where the pictures go")
    main(ap.parse_args().out)
