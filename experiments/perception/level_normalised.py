"""Every recording played at the corpus's median speech level before the speech model hears it (the front end
trained on real speech hears the same either way: it is level-invariant). The reference is the median speech
level (`audio.windows.speech_level`) of every 3rd train take of CACHE. Scored on val: RAVDESS's val actors
(one emotion a recording), the packaged real read speech at three gains, and the held-out synthetic voices under
changed recordings (perception_shift.py).

Usage: python experiments/perception/level_normalised.py SPEECH_MODEL CACHE RAVDESS_SCORING_MANIFEST OUT_DIR
"""
import runpy
import sys
from pathlib import Path

import numpy as np

from emogesture.audio import kaldi_fbank, load_audio
from emogesture.audio.windows import speech_level
from emogesture.data.cache import open_cache
from emogesture.pipeline.speech import SpeechLatentEncoder

speech, cache_dir, manifest, out = sys.argv[1:5]
cache = open_cache(cache_dir)
root = Path(cache.manifest["root"])
takes = sorted(set(cache.split("train").takes))[::3]
reference = float(np.median([speech_level(np.asarray(kaldi_fbank(load_audio(root / "wave16k" / f"{t}.wav")[0])))
                             for t in takes]))
print(f"reference level {reference:.3f} (natural log of power) from {len(takes)} train takes")
heard_as_recorded = SpeechLatentEncoder.encode


def encode(self, waveform, *args, **kwargs):
    w = np.asarray(waveform, np.float32)
    gain_db = (reference - speech_level(np.asarray(kaldi_fbank(w)))) * 10 / np.log(10)
    return heard_as_recorded(self, w * np.float32(10 ** (gain_db / 20)), *args, **kwargs)


SpeechLatentEncoder.encode = encode
Path(out).mkdir(parents=True, exist_ok=True)
here = Path(__file__).resolve().parents[1]
for script, args in ((here / "ravdess" / "perception_val.py", [speech, manifest, "val", f"{out}/ravdess_val.json"]),
                     (here / "real_perception.py", [f"{out}/real", f"level_normalised={speech}"]),
                     (here / "perception_shift.py", [speech, cache_dir, f"{out}/shift", "val"])):
    sys.argv = [str(script), *args]
    runpy.run_path(str(script), run_name="__main__")
