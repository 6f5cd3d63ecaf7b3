"""The import-linter contract in pyproject.toml: lower layers never import higher ones."""

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_import_layers_hold():
    exe = shutil.which("lint-imports") or str(Path(sys.executable).parent / "lint-imports")
    proc = subprocess.run([exe, "--no-cache"], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "KEPT" in proc.stdout


def test_importing_the_package_touches_nothing(tmp_path):
    """No downloads, files or environment changes at import: import in an empty cwd."""
    code = "import os, emogesture, emogesture.data.beat, emogesture.config; print(sorted(os.listdir('.')))"
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_the_public_api_is_the_package_s_and_loads_on_first_use():
    """``from emogesture import animate, AnimationRequest, GesturePipeline, GenerationConfig`` gives the
    pipeline's own objects; ``import emogesture`` alone loads no torch; an unknown name is an AttributeError."""
    code = ("import sys, emogesture\n"
            "assert 'torch' not in sys.modules\n"
            "from emogesture import animate, AnimationRequest, GesturePipeline, GenerationConfig\n"
            "from emogesture.pipeline.animate import animate as a, AnimationRequest as r\n"
            "from emogesture.pipeline.generate import GesturePipeline as p\n"
            "from emogesture.models.generation import GenerationConfig as g\n"
            "assert (animate, AnimationRequest, GesturePipeline, GenerationConfig) == (a, r, p, g)\n"
            "assert set(emogesture.__all__) >= {'animate', 'AnimationRequest', 'GesturePipeline', 'GenerationConfig'}\n"
            "try:\n    emogesture.nothing_here\nexcept AttributeError as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "no attribute 'nothing_here'" in out.stdout


def test_generating_a_familiar_voice_loads_no_heavy_library(tmp_path):
    """Start-up is most of a short clip's time: animating the demo speech (every window trusted, so the
    pitch-moved hearings do not run) imports no SciPy, scikit-learn or librosa (CTranslate2 it needs: the front
    end trained on real speech hears every recording)."""
    code = ("import sys\n"
            "from emogesture.cli.main import main\n"
            "from emogesture.assets import DEMO_CLIPS\n"
            f"sys.argv = ['emogesture', 'generate', str(DEMO_CLIPS / 'talk.flac'), '-o', r'{tmp_path}', '--format', 'npz', '--quiet']\n"
            "try:\n    main()\nexcept SystemExit as e:\n    assert not e.code, e.code\n"
            "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'sklearn', 'librosa'})\n"
            "print('heavy:', heavy)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "every window trusted" in out.stdout + out.stderr, out.stdout + out.stderr
    assert "heavy: []" in out.stdout, out.stdout
