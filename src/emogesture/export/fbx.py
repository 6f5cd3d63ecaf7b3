"""FBX (``.fbx``) through Blender: the glb's skinned mannequin, skeleton and animation, for Unity, Unreal,
Maya, MotionBuilder and 3ds Max.

The sequence is written as glTF (:mod:`emogesture.export.gltf`) and converted by Blender's own importer and
FBX exporter, run headless (``blender -b``): 55 bones with SMPL-X names (no leaf bones), the mannequin
skinned to them, the animation baked at every frame; metres, Y up, -Z forward (or Mixamo's 52 bones by
Mixamo's names). Blender is needed only for
this format: ``blender`` on ``PATH`` (Debian: ``apt-get install blender python3-numpy``; or blender.org), or
its path in ``EMOGESTURE_BLENDER``. Blender's FBX importer puts the first frame at frame 1.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from os import PathLike
from pathlib import Path

from emogesture.errors import EmogestureError
from emogesture.export.gltf import save_glb
from emogesture.fileio import atomic_output, check_output
from emogesture.types import SMPLXSequence

SCRIPT = Path(__file__).with_name("blender_fbx.py")
TIMEOUT_S = 1800


def blender_binary() -> str:
    """Blender's executable: ``EMOGESTURE_BLENDER``, else ``blender`` on ``PATH``; a one-line error saying
    what to install when there is none."""
    given = os.environ.get("EMOGESTURE_BLENDER")
    found = given or shutil.which("blender")
    if not found or not (os.path.isfile(found) and os.access(found, os.X_OK)):
        where = f"EMOGESTURE_BLENDER={given} is not an executable" if given else "blender is not installed"
        raise EmogestureError(f"fbx export runs Blender, and {where} (Debian/Ubuntu: apt-get install blender "
                              "python3-numpy; else blender.org, with EMOGESTURE_BLENDER=/path/to/blender)")
    return found


def save_fbx(seq: SMPLXSequence, path: str | PathLike[str], *, overwrite: bool = False,
             skeleton: str = "smplx") -> Path:
    """Write ``seq`` as FBX with the bones of ``skeleton`` (``smplx`` or ``mixamo``) through Blender (module
    docstring), atomically; refuses an existing file unless ``overwrite``."""
    check_output(path, overwrite)
    blender = blender_binary()
    with tempfile.TemporaryDirectory(prefix="emogesture-fbx-") as work, atomic_output(path, overwrite) as tmp:
        glb = save_glb(seq, Path(work) / f"{Path(path).stem}.glb", skeleton=skeleton)
        try:
            proc = subprocess.run([blender, "-b", "--factory-startup", "--python", str(SCRIPT), "--", str(glb),
                                   str(tmp), f"{float(seq.fps):g}"], capture_output=True, text=True,
                                  timeout=TIMEOUT_S, env={**os.environ, "PYTHONNOUSERSITE": "1"})
        except OSError as err:
            raise EmogestureError(f"{blender}: Blender cannot be run ({err.strerror or err})") from None
        except subprocess.TimeoutExpired:
            raise EmogestureError(f"{path}: Blender took over {TIMEOUT_S} s to write the fbx") from None
        output = proc.stdout + proc.stderr
        if "No module named 'numpy'" in output:
            raise EmogestureError(f"{path}: Blender's glTF importer needs numpy in Blender's Python (Debian: "
                                  "apt-get install python3-numpy)")
        if proc.returncode != 0 or not Path(tmp).is_file() or Path(tmp).stat().st_size == 0:
            lines = [ln.strip() for ln in output.splitlines() if "rror" in ln or "Traceback" in ln] or \
                [ln.strip() for ln in output.splitlines() if ln.strip()]
            raise EmogestureError(f"{path}: Blender could not write the fbx ({lines[-1] if lines else 'no output'})")
    return Path(path)


__all__ = ["blender_binary", "save_fbx"]
