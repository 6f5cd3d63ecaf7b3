"""The synthetic corpus (docs/design.md, 'Data' and 'Synthetic corpus'): layout, determinism, resume, and that
its factors are real.

One small corpus (4 speakers × 8 emotions × 3 texts, takes ≥ 8 s, 2 worker processes) is built
once for the module; a 1-speaker corpus (8 takes, in-process) checks determinism and resuming.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
import torch

from emogesture.audio import detect_onsets, kaldi_fbank, load_audio
from emogesture.data.beat import (
    EMOTIONS,
    SPEAKERS,
    group_takes_by_text,
    parse_take_name,
    read_sem,
    read_split_csv,
    read_textgrid_words,
)
from emogesture.data.synthetic import CorpusConfig, build_corpus, plan_takes, text_split
from emogesture.data.synthetic.speech import word_timings
from emogesture.data.synthetic.takes import TakePlan, build_take
from emogesture.errors import ConfigError, EmogestureError
from emogesture.motion import LOWER_BODY_JOINTS, UPPER_BODY_JOINTS, SkeletonBody, load_smplx_npz
from emogesture.motion.rotations import axis_angle_to_matrix

MIN_SECONDS = 8.0
SEED = 0
SCALE = CorpusConfig().emotion_prosody_scale  # the default emotion prosody strength
FILES = {"smplxflame_30": ".npz", "wave16k": ".wav", "textgrid": ".TextGrid", "sem": ".txt"}


def _config(**kw) -> CorpusConfig:
    base = dict(speakers=4, texts_per_emotion=3, min_take_seconds=MIN_SECONDS, seed=SEED, workers=2)
    base.update(kw)
    return CorpusConfig(**base)


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    root = tmp_path_factory.mktemp("corpus") / "beat2"
    summary = build_corpus(root, _config(), progress=False)
    return root, summary


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    root = tmp_path_factory.mktemp("mini") / "beat2"
    summary = build_corpus(root, _config(speakers=1, texts_per_emotion=1, workers=1), progress=False)
    return root, summary


def _bytes(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


# --- small pieces -------------------------------------------------------------------------------

def test_config_validation():
    for bad in (dict(speakers=0), dict(speakers=31), dict(texts_per_emotion=7), dict(workers=0),
                dict(engines=("say",)), dict(min_take_seconds=0.1), dict(emotion_prosody_scale=-1)):
        with pytest.raises(ConfigError):
            _config(**bad).validate()
    assert "workers" not in _config().identity()
    # scale 1 keeps the identity of corpora built before the setting existed; the default (1.5) is recorded
    assert "emotion_prosody_scale" not in _config(emotion_prosody_scale=1.0).identity()
    assert _config().identity()["emotion_prosody_scale"] == 1.5


def test_a_corpus_of_the_earlier_default_is_named_as_such():
    from emogesture.data.synthetic.corpus import CORPUS_VERSION, _differences

    now = {"version": CORPUS_VERSION, "config": _config().identity()}
    before = {"version": 1, "config": _config(emotion_prosody_scale=1.0).identity()}
    assert _differences(before, now) == \
        f"emotion_prosody_scale: 1.0 there, 1.5 here, version: 1 there, {CORPUS_VERSION} here"
    assert _differences(dict(now, version=1), now) == f"version: 1 there, {CORPUS_VERSION} here"
    # a corpus built with the removed speaker prosody scale (tried, not adopted) at another value than 1
    wide = {"version": CORPUS_VERSION, "config": dict(now["config"], speaker_prosody_scale=2.5)}
    assert _differences(wide, now) == "speaker_prosody_scale: 2.5 there, 1.0 here"
    assert _differences(None, now) == "unreadable marker"


def test_emotion_prosody_scale_scales_every_effect():
    from emogesture.data.synthetic.factors import EMOTION_FACTORS, Prosody, scale_prosody

    p = EMOTION_FACTORS["sadness"].prosody
    assert scale_prosody(p, 1.0) == p and scale_prosody(p, 0.0) == Prosody()
    q = scale_prosody(p, 2.0)
    assert q.pitch == 2 * p.pitch and q.gain_db == 2 * p.gain_db and q.tilt == 2 * p.tilt
    assert q.rate == pytest.approx(p.rate**2) and q.pitch_range == pytest.approx(p.pitch_range**2)
    assert q.breathiness == 2 * p.breathiness and q.tremolo == 2 * p.tremolo


def test_plan_holds_out_whole_texts():
    plans, splits = plan_takes(_config(speakers=3, texts_per_emotion=4))
    assert len(plans) == 3 * 8 * 4
    assert [text_split(i, 4) for i in range(4)] == ["train", "train", "val", "test"]
    assert [text_split(i, 2) for i in range(2)] == ["train", "test"]
    for (_, take), infos in group_takes_by_text(list(splits)).items():
        assert len({splits[i.name] for i in infos}) == 1  # every speaker of a text: same split
        assert len(infos) == 3


def test_word_timings_follow_voiced_segments():
    segments = [(0.5, 1.5), (2.0, 3.0)]
    words = word_timings("one two three four.", segments)
    assert [w for *_, w in words] == ["one", "two", "three", "four"]
    starts, ends = np.array([w[0] for w in words]), np.array([w[1] for w in words])
    assert np.all(ends > starts) and np.all(starts[1:] >= ends[:-1] - 1e-9)
    for s, e in zip(starts, ends):  # nobody straddles the pause
        assert (0.5 <= s and e <= 1.5 + 1e-9) or (2.0 - 1e-9 <= s and e <= 3.0 + 1e-9)


# --- the module corpus --------------------------------------------------------------------------

@pytest.mark.training
def test_layout_and_naming(corpus):
    root, summary = corpus
    assert summary.takes == 96 and summary.built == 96 and summary.splits == {"train": 64, "test": 32}
    names = sorted(p.stem for p in (root / "smplxflame_30").glob("*.npz"))
    assert len(names) == 96
    for sub, suffix in FILES.items():
        assert sorted(p.name for p in (root / sub).iterdir()) == sorted(n + suffix for n in names)
    splits = read_split_csv(root / "train_test_split.csv")
    assert sorted(splits) == names
    manifest = json.loads((root / "corpus.json").read_text())
    assert manifest["config"]["speakers"] == 4 and len(manifest["speakers"]) == 4
    for name in names:
        info = parse_take_name(name)
        assert info.speaker == SPEAKERS[info.speaker_id] and 1 <= info.speaker_id <= 4
        assert info.is_speech and manifest["takes"][name]["split"] == splits[name]
        text = next(t for t in manifest["texts"] if t["take"] == info.take)
        assert text["emotion"] == EMOTIONS[info.emotion]
        wav = sf.info(str(root / "wave16k" / f"{name}.wav"))
        assert (wav.samplerate, wav.channels, wav.subtype) == (16000, 1, "PCM_16")
        duration = wav.frames / 16000
        assert duration >= MIN_SECONDS
        seq = load_smplx_npz(root / "smplxflame_30" / f"{name}.npz")
        assert seq.poses.shape[1:] == (55, 3) and abs(seq.num_frames - round(duration * 30)) <= 1
        assert np.all(seq.poses[:, LOWER_BODY_JOINTS] == 0) and np.all(seq.trans == 0)
        assert np.isfinite(seq.poses).all() and np.abs(seq.poses).max() < np.pi
        words = read_textgrid_words(root / "textgrid" / f"{name}.TextGrid")
        assert len(words) >= 15 and words[-1][1] <= duration + 1e-3
        assert all(a < b for a, b, _ in words) and all(w1[1] <= w2[0] + 1e-6 for w1, w2 in zip(words, words[1:]))
        sem = read_sem(root / "sem" / f"{name}.txt")
        assert len(sem) >= duration * 0.3  # at least a stroke every ~3 s
        assert all(0 <= s.score <= 1 and 0 <= s.start < s.end <= duration for s in sem)


@pytest.mark.training
def test_every_speaker_speaks_every_text(corpus):
    root, _ = corpus
    for (_, take), infos in group_takes_by_text(sorted(p.stem for p in (root / "textgrid").iterdir())).items():
        assert [i.speaker_id for i in infos] == [1, 2, 3, 4]
        texts = [[w for *_, w in read_textgrid_words(root / "textgrid" / f"{i.name}.TextGrid")] for i in infos]
        shortest = min(texts, key=len)
        assert all(t[: len(shortest)] == shortest for t in texts)  # same text; a long take may add sentences


@pytest.mark.training
def test_motion_is_anatomically_plausible(corpus):
    root, _ = corpus
    body = SkeletonBody()
    for name in sorted(p.stem for p in (root / "smplxflame_30").glob("*.npz")):  # every take
        poses = load_smplx_npz(root / "smplxflame_30" / f"{name}.npz").poses
        joints = body(torch.from_numpy(poses)).numpy()
        # in the root's own frame: the body turns toward its listeners
        joints = np.einsum("tab,tja->tjb", axis_angle_to_matrix(torch.from_numpy(poses[:, 0]).double()).numpy(),
                           joints - joints[:, :1])
        wrists, shoulders, head, chest = joints[:, [20, 21]], joints[:, [16, 17]], joints[:, 15], joints[:, 9]
        assert np.all(wrists[..., 1] < head[:, None, 1])  # hands below the head
        assert np.all(wrists[..., 1] > shoulders[..., 1] - 0.65)  # and not below arm's length
        in_front = wrists[..., 2] - chest[:, None, 2] > 0.05
        behind = wrists[..., 2] - chest[:, None, 2] < -0.15  # behind the back (a hanging arm of a twisted torso)
        beside = np.abs(wrists[..., 0] - chest[:, None, 0]) > 0.17
        assert np.all(in_front | behind | beside), name  # never through the torso
        speed = np.linalg.norm(np.diff(wrists, axis=0), axis=-1) * 30
        assert speed.max() < 4.0 and speed.mean() > 0.02


# --- determinism and resume ---------------------------------------------------------------------

@pytest.mark.training
def test_same_seed_same_bytes(corpus, mini, tmp_path):
    """Takes do not depend on the corpus size, worker count or order: the 1-speaker corpus (built
    in-process) and single takes rebuilt here equal the module corpus (built by 2 workers)."""
    root, _ = corpus
    small, _ = mini
    for sub, suffix in FILES.items():
        for p in (small / sub).iterdir():
            assert p.read_bytes() == (root / sub / p.name).read_bytes(), p.name
    for plan in (TakePlan(2, 75, 2, 2, SEED, MIN_SECONDS, ("flite", "espeak-ng", "festival"), SCALE),  # espeak-ng
                 TakePlan(3, 104, 6, 1, SEED, MIN_SECONDS, ("flite", "espeak-ng", "festival"), SCALE)):  # festival
        build_take(tmp_path, plan)
        for sub, suffix in FILES.items():
            assert (tmp_path / sub / f"{plan.name}{suffix}").read_bytes() == \
                (root / sub / f"{plan.name}{suffix}").read_bytes()


@pytest.mark.training
def test_resume_rebuilds_exactly_the_damaged_takes(mini, tmp_path):
    src, _ = mini
    root = tmp_path / "copy"
    shutil.copytree(src, root)
    before = _bytes(root)
    assert build_corpus(root, _config(speakers=1, texts_per_emotion=1, workers=1), progress=False).built == 0
    assert _bytes(root) == before  # a complete corpus: nothing rewritten
    (root / "smplxflame_30" / "1_wayne_0_65_65.npz").unlink()
    wav = root / "wave16k" / "1_wayne_0_81_81.wav"
    wav.write_bytes(b"JUNK" + wav.read_bytes()[4:])  # broken RIFF header
    (root / "corpus.json").unlink()  # as if interrupted before the end
    (root / "sem" / ".1_wayne_0_1_1.txt.123.abcd.tmp").write_text("partial")
    summary = build_corpus(root, _config(speakers=1, texts_per_emotion=1, workers=1), progress=False)
    assert (summary.built, summary.skipped) == (2, 6)
    assert _bytes(root) == before
    with pytest.raises(EmogestureError, match=rf"other settings \(seed: {SEED} there, {SEED + 1} here\)"):
        build_corpus(root, _config(speakers=1, texts_per_emotion=1, seed=SEED + 1), progress=False)
    with pytest.raises(EmogestureError, match="already holds"):
        build_corpus(root, _config(speakers=1, texts_per_emotion=1), progress=False, resume=False)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    (tmp_path / "other" / "wave16k").mkdir()  # e.g. a real BEAT2 copy: never deleted, not even with overwrite
    (tmp_path / "other" / "wave16k" / "a.wav").write_text("theirs")
    for overwrite in (False, True):
        with pytest.raises(EmogestureError, match="not a synthetic corpus"):
            build_corpus(tmp_path / "other", _config(speakers=1, texts_per_emotion=1), progress=False,
                         overwrite=overwrite)
    assert (tmp_path / "other" / "wave16k" / "a.wav").read_text() == "theirs"
    (root / "notes.txt").write_text("mine")
    summary = build_corpus(root, _config(speakers=1, texts_per_emotion=1, seed=SEED + 1), progress=False,
                           overwrite=True)  # the corpus of other settings, rebuilt; the user's file kept
    assert summary.built == 8 and (root / "notes.txt").read_text() == "mine"
    assert json.loads((root / "corpus.json").read_text())["config"]["seed"] == SEED + 1
    assert _bytes(root).keys() == before.keys() | {"notes.txt"} and _bytes(root) != before


# --- the generating factors are recoverable -----------------------------------------------------

def _audio_features(wave: np.ndarray) -> np.ndarray:
    """Mean and std over time of the 128 log-mel bins, plus loudness, voiced share and onset rate."""
    fb = kaldi_fbank(wave).numpy()
    level = fb[:, :100].mean(axis=1)
    voiced = level > np.percentile(level, 95) - 8.0
    onsets_per_voiced_s = len(detect_onsets(wave)) / (voiced.mean() * len(wave) / 16000)
    return np.concatenate([fb.mean(0), fb.std(0), [level[voiced].mean(), voiced.mean(), onsets_per_voiced_s]])


def _motion_features(poses: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """Mean and std of the upper-body axis-angle poses and of the upper-body joint speeds (FK)."""
    p = poses[:, UPPER_BODY_JOINTS].reshape(len(poses), -1)
    v = np.linalg.norm(np.diff(joints[:, UPPER_BODY_JOINTS], axis=0), axis=-1) * 30
    return np.concatenate([p.mean(0), p.std(0), v.mean(0), v.std(0)])


@pytest.fixture(scope="module")
def measured(corpus):
    root, _ = corpus
    body = SkeletonBody()
    splits = read_split_csv(root / "train_test_split.csv")
    rows = []
    for name in sorted(splits):
        info = parse_take_name(name)
        wave, _ = load_audio(root / "wave16k" / f"{name}.wav")
        seq = load_smplx_npz(root / "smplxflame_30" / f"{name}.npz")
        joints = body(torch.from_numpy(seq.poses)).numpy()
        rows.append(dict(emotion=info.emotion, speaker=info.speaker_id, split=splits[name],
                         audio=_audio_features(wave), motion=_motion_features(seq.poses, joints),
                         seconds=len(wave) / 16000))
    return rows


@pytest.mark.training
def test_emotion_and_speaker_recoverable_from_audio_and_motion(measured):
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    train = np.array([r["split"] == "train" for r in measured])
    test = np.array([r["split"] == "test" for r in measured])
    results = {}
    for modality in ("audio", "motion"):
        x = np.stack([r[modality] for r in measured])
        for factor in ("emotion", "speaker"):
            y = np.array([r[factor] for r in measured])
            clf = make_pipeline(StandardScaler(), LogisticRegression(C=0.1, max_iter=5000))
            clf.fit(x[train], y[train])
            results[(modality, factor)] = float((clf.predict(x[test]) == y[test]).mean())
    print("\nheld-out-text accuracy (chance: emotion 0.125, speaker 0.25):",
          {f"{m}/{f}": round(a, 3) for (m, f), a in results.items()})
    assert results[("audio", "emotion")] >= 0.6
    assert results[("motion", "emotion")] >= 0.6
    assert results[("audio", "speaker")] >= 0.75
    assert results[("motion", "speaker")] >= 0.75


@pytest.mark.training
def test_motion_follows_the_speech_at_a_persons_level(corpus):
    """The arms' speed follows the take's own onsets (the onset coupling of ``motion-stats``) more than the
    same audio shifted in time, and not as tightly as a corpus that strokes on every syllable. (Against a
    real take's 0.05, on whole takes: ``experiments/motion_realism.py``; these 8-s takes read higher.)"""
    from scipy.stats import wilcoxon

    from emogesture.eval.motion_stats import onset_coupling

    root, _ = corpus
    body = SkeletonBody()
    own, shifted = [], []
    for f in sorted((root / "smplxflame_30").glob("*.npz")):
        joints = body(torch.from_numpy(load_smplx_npz(f).poses)).numpy()
        wave, sr = load_audio(root / "wave16k" / f"{f.stem}.wav")
        own.append(onset_coupling(joints, wave, sr, 30.0))
        shifted.append(np.mean([onset_coupling(joints, np.roll(wave, int(s * sr)), sr, 30.0)
                                for s in (1.1, 2.3, len(wave) / sr / 2)]))
    own, shifted = np.array(own), np.array(shifted)
    p = wilcoxon(own, shifted).pvalue
    print(f"\nonset coupling: own audio {own.mean():.3f}, shifted {shifted.mean():.3f}, own > shifted in "
          f"{(own > shifted).mean():.0%} of takes, Wilcoxon p = {p:.1e}")
    assert (own > shifted).mean() >= 0.6 and p < 0.01  # present, weak (unrelated motion: about 50 %, p ~ 0.5)
    assert own.mean() <= 0.15  # corpus version 4 ticked on every syllable: about 0.2 on these short takes


# Real conversational motion capture (BEAT, two speakers; docs/design.md, 'How real motion moves'): mean angular
# speed of each joint's local rotation, rad per 30-fps frame, (speaker 2, speaker 1).
REAL_ANGULAR_SPEED = {
    "spine1": (0.0072, 0.0044), "spine2": (0.0062, 0.0034), "spine3": (0.0037, 0.0024), "neck": (0.0105, 0.0051),
    "head": (0.0099, 0.0061), "left_collar": (0.0147, 0.0056), "right_collar": (0.0137, 0.0047),
    "left_shoulder": (0.0238, 0.0103), "right_shoulder": (0.0197, 0.0110), "left_elbow": (0.0454, 0.0099),
    "right_elbow": (0.0487, 0.0203), "left_wrist": (0.0378, 0.0230), "right_wrist": (0.0408, 0.0324),
}


@pytest.mark.training
def test_motion_moves_like_real_motion(corpus):
    """Every upper-body joint turns within [0.5 × the slower, 1.5 × the faster] real speaker; hand speed and
    posture within the ranges of real motion (wrists pooled)."""
    from emogesture.eval.motion_stats import file_statistics

    root, _ = corpus
    r = file_statistics(sorted((root / "smplxflame_30").glob("*.npz")))
    print("\nmotion statistics:", {k: round(v, 4) for k, v in r["angular_speed"].items()},
          {k: round(r[k], 3) for k in ("wrist_speed_mean", "wrist_below_pelvis_share", "elbow_open_share",
                                        "wrist_still_share")})
    for joint, (a, b) in REAL_ANGULAR_SPEED.items():
        assert 0.5 * min(a, b) <= r["angular_speed"][joint] <= 1.5 * max(a, b), joint
    assert 0.25 <= r["wrist_speed_mean"] <= 0.6
    assert 0.25 <= r["wrist_below_pelvis_share"] <= 0.6
    assert 0.05 <= r["elbow_open_share"] <= 0.25
    assert r["wrist_still_share"] <= 0.10
