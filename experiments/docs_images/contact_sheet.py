"""A contact sheet of motion: one row per source, a pose every second (how lively each source looks).

Usage: .venv/bin/python experiments/docs_images/contact_sheet.py OUT.png [--start S] [--count N] LABEL=FILE.npz ...
Each row draws FILE.npz (a BEAT2/SMPL-X sequence) with the preview video's mannequin at S, S+1, ...
S+N-1 seconds, with the same camera for every row (fitted to the first).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from emogesture.export.video import Camera, MannequinRenderer
from emogesture.fileio import atomic_output
from emogesture.motion import SkeletonBody, load_smplx_npz


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("rows", nargs="+", metavar="LABEL=FILE.npz")
    ap.add_argument("--start", type=float, default=2.0)
    ap.add_argument("--count", type=int, default=6)
    ap.add_argument("--overwrite", action="store_true")
    args = ap.parse_args()
    w, h, label_w = 200, 240, 150
    renderer = MannequinRenderer(w, h)
    camera = None
    sheet = Image.new("RGB", (label_w + w * args.count, h * len(args.rows)), "white")
    draw = ImageDraw.Draw(sheet)
    for r, item in enumerate(args.rows):
        label, _, path = item.partition("=")
        seq = load_smplx_npz(path)
        camera = camera or Camera.upper_body(seq, w, h)
        import torch

        with torch.no_grad():
            joints = SkeletonBody(seq.betas)(torch.from_numpy(seq.poses), torch.from_numpy(seq.trans)).numpy()
        for c in range(args.count):
            frame = int(round((args.start + c) * seq.fps))
            img = renderer.draw(joints[min(frame, len(joints) - 1)], camera)
            sheet.paste(Image.fromarray(img), (label_w + c * w, r * h))
        draw.text((8, r * h + h // 2 - 10), label.replace("\\n", "\n"), fill="black")
    for c in range(args.count):
        draw.text((label_w + c * w + 6, 4), f"{args.start + c:.0f} s", fill="black")
    with atomic_output(args.out, args.overwrite) as tmp:
        sheet.save(tmp, format="PNG", optimize=True)
    print(f"wrote {args.out} ({np.prod(sheet.size) // 1000} kpx)")


if __name__ == "__main__":
    main()
