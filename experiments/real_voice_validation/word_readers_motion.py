"""The motion a gesture model makes for the validation set of real voices, against held-out corpus takes.

``emogesture evaluate real`` reads the real-speech check recordings; this reads the thirteen volunteers
reading word lists (:data:`emogesture.data.real_speech.WORD_READERS`, never trained or calibrated on) the
same way (:func:`emogesture.eval.real_speech.real_speech_report`): the first :data:`SECONDS` of each, read
without acted emotion, beside the ``split``'s neutral corpus takes, generated as ``generate`` does by default
(``--emotion auto``) with each sampling seed: what is heard and trusted, a hand in front of the chest and the
wrists' distance, per reader and pooled, with the real-speech checks' bars. With ``--neutral-reference``,
each reader is heard and generated against the :data:`REFERENCE_SECONDS` that follow the first
:data:`SECONDS` of the same reader (``generate --neutral-from``; :mod:`emogesture.pipeline.neutral_reference`).

Usage: python experiments/real_voice_validation/word_readers_motion.py GESTURE_MODEL CACHE OUT_DIR [SPLIT] [SEEDS] [--neutral-reference]
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
REFERENCE_SECONDS = 20


def main(model: str, cache_dir: str, out_dir: str, split: str = "val", seeds: str = "2",
         neutral_reference: bool = False) -> None:
    waves = {name: load_voice(voice) for name, voice in WORD_READERS.items()}
    recordings = {name: (wave[: SECONDS * TARGET_SAMPLE_RATE], "neutral") for name, wave in waves.items()}
    neutral = ({name: wave[SECONDS * TARGET_SAMPLE_RATE:(SECONDS + REFERENCE_SECONDS) * TARGET_SAMPLE_RATE]
                for name, wave in waves.items()} if neutral_reference else None)
    pipe = GesturePipeline.from_run(model)
    reference = reference_recordings(open_cache(cache_dir), split, {"neutral"})
    result = real_speech_report(pipe, recordings, reference, list(range(int(seeds))), progress=True,
                                neutral_references=neutral)
    against = (f"; each heard and generated against the next {REFERENCE_SECONDS} s of the same reader "
               "(--neutral-from)" if neutral_reference else "")
    result["header"] = (f"The validation set of real voices (thirteen volunteers reading word lists, the first "
                        f"{SECONDS} s of each; never trained or calibrated on{against}) against the {split} split's "
                        f"neutral takes; model {pipe.loaded.path}.")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = "word_readers_motion" + ("_neutral_reference" if neutral_reference else "")
    (out / f"{stem}.json").write_text(json.dumps(result, indent=1) + "\n")
    (out / f"{stem}.md").write_text(real_speech_markdown(result))
    print(real_speech_markdown(result))


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--neutral-reference"]
    if len(args) < 3:
        sys.exit(__doc__)
    main(*args, neutral_reference="--neutral-reference" in sys.argv[1:])
