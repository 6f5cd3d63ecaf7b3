"""Helpers shared by the tests: a small BEAT2-layout folder and the command line."""

import sys
from pathlib import Path

import numpy as np
import soundfile as sf

from emogesture.data.beat import format_take_name, write_split_csv
from emogesture.motion import save_smplx_npz
from emogesture.types import SMPLXSequence

SECONDS = 21.0


def make_root(root: Path, speakers=(1, 2), takes=(1, 2, 65, 66), seed=0) -> list[str]:
    """A small BEAT2-layout folder: tone-burst audio and smooth random upper-body motion."""
    rng = np.random.default_rng(seed)
    for d in ("smplxflame_30", "wave16k", "sem"):
        (root / d).mkdir(parents=True, exist_ok=True)
    names, splits = [], {}
    t = np.arange(int(SECONDS * 16000)) / 16000
    for spk in speakers:
        for take in takes:
            name = format_take_name(spk, take)
            names.append(name)
            f0 = 120 + 40 * spk + take
            wave = 0.3 * np.sin(2 * np.pi * f0 * t) * (np.sin(2 * np.pi * 2.0 * t) > 0)
            sf.write(root / "wave16k" / f"{name}.wav", wave.astype(np.float32), 16000, subtype="PCM_16")
            T = int(SECONDS * 30)
            poses = np.cumsum(rng.normal(0, 0.01, (T, 55, 3)), axis=0).astype(np.float32)
            save_smplx_npz(SMPLXSequence(poses=poses, trans=np.zeros((T, 3))), root / "smplxflame_30" / f"{name}.npz")
            (root / "sem" / f"{name}.txt").write_text("beat\t1.0\t2.0\t1.0\t0.5\tword\n")
            splits[name] = "test" if take in (2, 66) else "train"
    write_split_csv(root / "train_test_split.csv", splits)
    return names


def cli(*args) -> list[str]:
    """The ``emogesture`` command line run with this interpreter."""
    return [sys.executable, "-m", "emogesture.cli.main", *map(str, args)]
