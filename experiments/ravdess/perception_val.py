"""A speech model's emotion perception on the speakers of one split of a labelled-speech manifest (RAVDESS's
actors): each speaker's clips of one emotion joined into one recording and heard window by window (10-s
windows every 7 s, as `generate` hears them; calm counted as neutral when the manifest says so). Writes the
per-emotion accuracy, the confusion matrix, the share of windows `--emotion auto` trusts and every window's
label to OUT.json, and prints the summary.

Usage: perception_val.py SPEECH_MODEL MANIFEST SPLIT OUT.json [SEMITONES]
(the front end trained on real speech hears the windows where the perception reads it; SEMITONES: the pitch-shifted hearings, as the generation setting perception_semitones; default: the setting of
the gesture model beside SPEECH_MODEL when it is a bundle's speech.json, else 3)"""
import json, sys
from collections import Counter, defaultdict
import numpy as np
from emogesture.data.labelled_speech import labelled_recordings, read_manifest
from emogesture.pipeline.generate import bundle_generation
from emogesture.pipeline.speech import SpeechLatentEncoder
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.types import EMOTIONS

model, manifest, split, out = sys.argv[1:5]
semis = float(sys.argv[5]) if len(sys.argv) > 5 else bundle_generation(model).perception_semitones
enc = SpeechLatentEncoder.from_run(model)
perc = perception_of(enc)
recs = labelled_recordings(read_manifest(manifest), split, 10.0)
conf = defaultdict(Counter); trusted = []; rows = {}
for name, (wave, emotion) in recs.items():
    e, starts = enc.encode(wave, hop_seconds=7.0, perception_semitones=semis, front_end=True)
    heard = perceive(e, starts, perc, name)
    for lab in heard.labels:
        conf[emotion][lab] += 1
    if heard.trust is not None:
        trusted += [float(t >= 1.0) for t in heard.trust]
    rows[name] = heard.labels
right = sum(conf[e][e] for e in conf); total = sum(sum(c.values()) for c in conf.values())
per = {e: round(conf[e][e] / max(1, sum(conf[e].values())), 3) for e in EMOTIONS if e in conf}
res = {"model": model, "split": split, "perception_semitones": semis, "windows": total, "accuracy": round(right / total, 4), "per_emotion": per,
       "trusted": round(float(np.mean(trusted)), 3) if trusted else None,
       "confusion": {e: dict(conf[e]) for e in conf}, "recordings": rows}
json.dump(res, open(out, "w"), indent=1)
print(json.dumps({k: res[k] for k in ("model", "split", "windows", "accuracy", "per_emotion", "trusted")}))
