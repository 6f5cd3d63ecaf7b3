"""RAVDESS val actors heard by read-outs of the speech model's latents (logistic regressions fitted on the train
actors) against the shipped read-out (experiments/ravdess/reports/front_end_val.md).

Usage: front_end_latents.py SPEECH_MODEL TRAIN_MANIFEST SCORING_MANIFEST OUT_DIR
(TRAIN_MANIFEST: calm left out; SCORING_MANIFEST: calm as neutral)"""
import sys, numpy as np
from collections import Counter
from emogesture.data.labelled_speech import labelled_recordings, read_manifest
from emogesture.pipeline.speech import SpeechLatentEncoder
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.types import EMOTIONS
from sklearn.linear_model import LogisticRegression
from sklearn.preprocessing import StandardScaler
from sklearn.pipeline import make_pipeline
model, train_manifest, scoring_manifest, out = sys.argv[1:5]
enc = SpeechLatentEncoder.from_run(model); perc = perception_of(enc)
def feats(manifest, split, hop, semis=0.0):
    X, S, L, Y, cur = [], [], [], [], []
    for name, (wave, emotion) in labelled_recordings(read_manifest(manifest), split, 10.0).items():
        e, starts = enc.encode(wave, hop_seconds=hop, perception_semitones=semis)
        X.append(e.emotion); S.append(e.style); L.append(e.emotion_logits); Y += [EMOTIONS.index(emotion)] * len(starts)
        if semis:
            cur += perceive(e, starts, perc, name).labels
    return np.concatenate(X), np.concatenate(S), np.concatenate(L), np.array(Y), cur
tr = feats(train_manifest, "train", 3.0)
np.savez(f"{out}/latents_train.npz", X=tr[0], S=tr[1], L=tr[2], Y=tr[3])
va = feats(scoring_manifest, "val", 7.0, 3.0)
np.savez(f"{out}/latents_val.npz", X=va[0], S=va[1], L=va[2], Y=va[3], cur=np.array([EMOTIONS.index(c) for c in va[4]]))
print("train windows", len(tr[3]), Counter(tr[3].tolist()), "val windows", len(va[3]))
print("current read-out val acc", np.mean(np.array([EMOTIONS.index(c) for c in va[4]]) == va[3]))
for C in (0.01, 0.1, 1.0):
    for name, f in (("emotion", lambda d: d[0]), ("emotion+logits", lambda d: np.hstack([d[0], d[2]]))):
        clf = make_pipeline(StandardScaler(), LogisticRegression(C=C, max_iter=3000)).fit(f(tr), tr[3])
        print(name, "C", C, "val acc %.3f" % np.mean(clf.predict(f(va)) == va[3]))
