"""The motion a gesture model makes for the validation set of real voices, against held-out corpus takes.

``emogesture evaluate real`` reads the real-speech check recordings; this reads the thirteen volunteers
reading word lists (:data:`emogesture.data.real_speech.WORD_READERS`, never trained or calibrated on) the
same way (:func:`emogesture.eval.real_speech.real_speech_report`): the first :data:`SECONDS` of each, read
without acted emotion, beside the ``split``'s neutral corpus takes, generated as ``generate`` does by default
(``--emotion auto``) with each sampling seed: what is heard and trusted, a hand in front of the chest and the
wrists' distance, per reader and pooled, with the real-speech checks' bars.

Usage: python experiments/word_readers_motion.py GESTURE_MODEL CACHE OUT_DIR [SPLIT] [SEEDS]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from emogesture.audio import TARGET_SAMPLE_RATE
from emogesture.data.cache import open_cache
from emogesture.data.real_speech import WORD_READERS, load_voice
from emogesture.eval.real_speech import real_speech_markdown, real_speech_report, reference_recordings
from emogesture.pipeline.generate import GesturePipeline

SECONDS = 40


def main(model: str, cache_dir: str, out_dir: str, split: str = "val", seeds: str = "2") -> None:
    recordings = {name: (load_voice(voice)[: SECONDS * TARGET_SAMPLE_RATE], "neutral")
                  for name, voice in WORD_READERS.items()}
    pipe = GesturePipeline.from_run(model)
    reference = reference_recordings(open_cache(cache_dir), split, {"neutral"})
    result = real_speech_report(pipe, recordings, reference, list(range(int(seeds))), progress=True)
    result["header"] = (f"The validation set of real voices (thirteen volunteers reading word lists, the first "
                        f"{SECONDS} s of each; never trained or calibrated on) against the {split} split's neutral "
                        f"takes; model {pipe.loaded.path}.")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "word_readers_motion.json").write_text(json.dumps(result, indent=1) + "\n")
    (out / "word_readers_motion.md").write_text(real_speech_markdown(result))
    print(real_speech_markdown(result))


if __name__ == "__main__":
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    main(*sys.argv[1:])
