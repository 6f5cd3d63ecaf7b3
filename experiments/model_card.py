"""Writes the bundled model's card (MODEL_CARD.md + card.json) from its evaluation reports, then its
SHA256SUMS. Called by experiments/bundled_model.sh.

Usage: python experiments/model_card.py BUNDLE_DIR REPORT_DIR TIMES_TXT CACHE_DIR
"""

from __future__ import annotations

import json
import re
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from emogesture.bundle import write_checksums
from emogesture.checkpoints import write_text_atomic
from emogesture.data.synthetic.corpus import CORPUS_VERSION, MARKER
from emogesture.eval.real_speech import heard_text
from emogesture.pipeline.generate import HOP_SECONDS
from emogesture.train.perception import NOISE_SNR_DB, QUIETER_DB
from emogesture.types import EMOTIONS

REBUILD = ("make model RAVDESS=/path/to/audio_speech_actors_01-24   # = bash experiments/bundled_model.sh "
           "(resumes when re-run; without RAVDESS=: the synthetic corpus alone)")
#: RAVDESS's actor split (experiments/recipe.sh's RAVDESS_SPLIT)
RAVDESS_VAL, RAVDESS_TEST = "actors 2, 3 and 12", "actors 8, 17 and 19"


def training_minutes(lines: list[str]) -> int:
    """The trainings' total wall time in minutes, from the times file's lines (``name: SECONDS s``)."""
    return round(sum(float(line.split(":")[1].split()[0]) for line in lines) / 60)


def rhythm_paragraph(rows: dict, checks: dict) -> str:
    """What the test report's rhythm checks say about the strokes' timing: they follow the
    speech when the gain reaches 0.6 of the ground truth's and another window's timing stream takes it
    to within noise of zero."""
    gt, ours = rows["GT"]["rhythm"], rows["ours"]["rhythm"]
    other = rows.get("ours, timing stream of another window", {}).get("rhythm")
    passed = [v["pass"] for k, v in checks.items()
              if k.startswith("rhythm: gain / the ground truth's gain") or k.startswith("rhythm: ours, timing stream")]
    if len(passed) == 2 and all(passed):
        return (f"- **Strokes on the syllables.** Within each 10-s window the strokes follow the speech's timing: the\n"
                f"  rhythm gain (how much better the arms' speed follows the speech's onsets than mismatched audio's)\n"
                f"  is {ours['gain']:.3f} on the test texts ({ours['gain_over_spread']:.1f} spreads of the mismatched "
                f"scores), against\n  {gt['gain']:.3f} for the corpus's own motion; generated with another window's "
                f"timing stream it falls to\n  {other['gain']:.3f} (`experiments/rhythm/README.md`).")
    return (f"- **The strokes do not yet fall on the syllables.** Within a window the strokes are not timed by the\n"
            f"  speech: the rhythm gain is {ours['gain']:.3f} ({ours['gain_over_spread']:.1f} spreads) on the test texts,\n"
            f"  against {gt['gain']:.3f} for the corpus's own motion (`experiments/rhythm/README.md`).")


def seams_paragraph(checks: dict) -> str:
    """What the test report's long-audio checks say about the seams between 10-s windows."""
    def value(start: str, contains: str = "") -> tuple[str, dict]:
        return next((k, v) for k, v in checks.items() if k.startswith(start) and contains in k)
    name, stretch = value("long audio, 1 candidate per window, ", "p99 seam jump / p99 inside")
    pooled = re.search(r"(\d+) stretches", name)
    where = f"{pooled.group(1)} 65-s stretches" if pooled else "a 65-s stretch"
    real = value("long audio, ground truth of the same stretch")[1]
    whole = value("every take whole, 1 candidate: p99 seam jump / p99 inside")[1]
    own = next((v for k, v in checks.items() if k.startswith("long audio, 1 candidate per window: p99 seam jump / "
                                                               "the windows' own")), None)
    verdict = ("the seams move no more than the motion inside a window" if stretch["pass"] and whole["pass"]
               else "**the seams sometimes move more than the motion inside a window**")
    cause = ""
    if own is not None:
        cause = (f"\n  The cross-fade itself {'adds no fast jumps' if own['pass'] else '**adds fast jumps**'}: at the "
                 f"seams of {'those stretches' if pooled else 'that stretch'}\n  the stitched motion's 99th-percentile jump is {own['value']:.2f} of what "
                 f"the faster of the two windows\n  makes there on its own (the bar is 1)."
                 + (" The seams' fast tail is the windows' own strokes." if own["pass"] else ""))
    return (f"- **Long audio.** Audio longer than 10 s is generated as 10-s windows every {HOP_SECONDS:g} s, cross-faded over the\n"
            f"  overlaps: {verdict} (99th-percentile frame-to-frame joint\n"
            f"  jump at the seams over that inside windows: {stretch['value']:.3f} on {where} of the test "
            f"texts, whose real\n  motion gives {real['value']:.2f}; {whole['value']:.2f} over every test take "
            f"generated whole; the bar is 1).{cause}")


def corpus_paragraph(cache_dir: Path) -> str:
    """The training corpus in numbers, read from the cache and the corpus it was prepared from."""
    manifest = json.loads((cache_dir / "manifest.json").read_text())
    corpus = json.loads((Path(manifest["root"]) / "corpus.json").read_text())
    windows = manifest["windows"]
    speakers = corpus["speakers"]
    minutes = sum(t["seconds"] for t in corpus["takes"].values()) / 60
    engines = sorted({v["voice"]["engine"] for v in speakers.values()})
    return (f"{len(speakers)} synthetic speakers, each its own voice ({', '.join(engines)}) with its own pitch and rate, "
            f"8 emotions with their own prosody, {len(corpus['texts'])} texts, {len(corpus['takes'])} takes, "
            f"{minutes:.1f} minutes of speech; the motion is procedural upper-body gestures timed by the speech "
            f"onsets, with per-emotion and per-speaker signatures. No recorded human speech and no motion capture. "
            f"Splits hold out texts and speakers together (`prepare --set split_source=csv+actor`): a take is test "
            f"when its text or its speaker is, else val when either is. Train: the train speakers' train texts "
            f"({windows['train']} windows); val ({windows['val']} windows) and test ({windows['test']} windows) "
            f"hold voices never heard in training, among them two whole voice families (festival's diphone voices, "
            f"espeak-ng's Klatt voices).")


def real_rows(real: dict) -> str:
    """The real-speech report's perception and motion, as table rows."""
    m, p = real["motion"], real["pooled"]
    return "\n".join([
        f"| windows heard as neutral (`--emotion own`) | {p['real']['heard_share']:.0%} of {p['real']['windows']} | "
        f"{p['reference']['heard_share']:.0%} of {p['reference']['windows']} |",
        f"| windows `--emotion auto` trusts | {p['real']['trusted_share']:.0%} | {p['reference']['trusted_share']:.0%} |",
        f"| a hand ≥ 0.15 m in front of the chest | {m['real']['hand_in_front_share']:.1%} | "
        f"{m['reference']['hand_in_front_share']:.1%} |",
        f"| wrists' median distance | {m['real']['wrist_distance_median']:.3f} m | "
        f"{m['reference']['wrist_distance_median']:.3f} m |"])


def real_recording_text(real: dict) -> str:
    """Each real recording's perception: what it is heard as, and how many of its windows `auto` trusts."""
    def one(name: str, r: dict) -> str:
        return f"{name} heard as {heard_text(r['heard_counts'])}, {sum(r['trusted'] or [])} of {r['windows']} windows trusted"

    return "; ".join(one(name, r) for name, r in real["real"].items())


def level_paragraph(rows: dict) -> str:
    """What the recording's level does to the perception (perception_shift's level rows), or nothing."""
    level = {name: r for name, r in rows.items() if name.startswith("recording level")}
    if not level:
        return ""

    def heard(r: dict) -> str:
        top = max(r["perceived_emotions"].items(), key=lambda kv: kv[1])
        return f"correct in {r['perceived_correctly']:.0%} of the windows, mostly as {top[0]} ({top[1]:.0%})"

    parts = "; ".join(f"{name[len('recording level '):]}: {heard(r)}" for name, r in level.items())
    return ("\n  The recording's level changes what it hears (the same held-out takes, only louder or quieter; "
            f"{parts}). The training voices' loudness goes with their emotion, and the perception learned it: "
            "a quiet or a loud microphone moves the perceived emotion, so set the emotion yourself when in doubt.\n")


def fallback_sentence(record: dict | None) -> str:
    """What the card says of the gesture model's fallback style (``emogesture calibrate style``)."""
    if not record:
        return "The fallback is the training voice nearest the centre of the training voices."
    chosen, ref = record["candidates"][str(record["speaker"])], record["reference"]
    shares = sorted(c["in_front"] for c in record["candidates"].values())
    return (f"The fallback is training speaker {record['speaker']}, whose style gives the model's typical motion: "
            f"on {record['windows']} neutral {record['split']} windows with the neutral emotion and each training "
            f"speaker's style in turn, a hand is in front of the chest in {shares[0]:.0%} to {shares[-1]:.0%} of "
            f"the frames, {chosen['in_front']:.0%} with this one, {ref['in_front']:.0%} with the windows' own.")


def fallback_table(record: dict) -> str:
    """The fallback-style choice as a markdown report: every candidate speaker against the reference."""
    ref = record["reference"]
    rows = "\n".join(f"| {k}{' (chosen)' if int(k) == record['speaker'] else ''} | {c['in_front']:.1%} | "
                     f"{c['wrist_distance']:.3f} | {c['cost']:.2f} |"
                     for k, c in sorted(record["candidates"].items(), key=lambda kv: kv[1]["cost"]))
    return (f"# The fallback style for unfamiliar voices (split {record['split']})\n\n"
            f"{record['windows']} neutral windows of the {record['split']} split (held-out voices), seed "
            f"{record['seed']}: generated with their own latents (the reference), then with the neutral mean "
            "emotion latent and each training speaker's mean style latent (`emogesture calibrate style`). "
            "Cost: the distance from the reference in units of the real-speech check's tolerances (0.10 in "
            "the share, 10 % in the distance).\n\n"
            f"| style | a hand in front of the chest | wrists' median distance (m) | cost |\n|---|---|---|---|\n"
            f"| the windows' own (reference) | {ref['in_front']:.1%} | {ref['wrist_distance']:.3f} | - |\n{rows}\n")


def word_readers_text(path: Path) -> str:
    """The model's perception of the validation set of real voices (``word_readers.py``), when measured."""
    if not path.is_file():
        return ""
    r = next(iter(json.loads(path.read_text()).values()))
    heard = Counter(k for reader in r["readers"].values() for k in reader["heard"])
    return (f"\n  More real voices tell the same, worse: {len(r['readers'])} volunteers reading word lists (KDE's "
            f"KTuberling, `experiments/word_readers.py`; never trained or calibrated on) are heard as neutral in "
            f"{r['neutral_share']:.0%} of {sum(heard.values())} stretches ({heard_text(heard)}), trusted in "
            f"{r['trusted_share']:.0%}; given each emotion's prosody as the corpus gives it, they are heard as that "
            f"emotion in {r['emotions_mean']:.0%} (mean of the seven).")


def neutral_reference_text(path: Path) -> str:
    """What a neutral recording of the same speaker (``neutral_reference.py``) changes, when measured."""
    if not path.is_file():
        return ""
    r = next(iter(json.loads(path.read_text()).values()))
    readers, voices = r["readers"], r["held_out_voices"]["rows"]
    changed = [row for name, row in voices.items() if name != "as recorded"]
    return (f" Given a recording of the same reader speaking without emotion (`generate --neutral-from`, "
            f"`experiments/neutral_reference.py`, val), the same stretches are heard as neutral in "
            f"{readers['both']['neutral_share']:.0%} (alone: {readers['alone']['neutral_share']:.0%}) and the "
            f"emotions given them in {readers['both']['emotions_mean']:.0%} "
            f"({readers['alone']['emotions_mean']:.0%}); the held-out synthetic voices under the seven changed "
            f"recordings are heard right in {np.mean([row['both'] for row in changed]):.1%} "
            f"({np.mean([row['alone'] for row in changed]):.1%}).")


def ravdess_section(path: Path) -> str:
    """The RAVDESS test actors' table (per emotion, confusion matrix) when the bundle was trained with RAVDESS
    and scored on its test actors (experiments/ravdess/perception_val.py), else nothing."""
    if not path.exists():
        return ""
    r = json.loads(path.read_text())
    conf = r["confusion"]
    order = [e for e in EMOTIONS if e in conf]
    heard = sorted({k for row in conf.values() for k in row}, key=EMOTIONS.index)
    rows = "\n".join(f"| {e} | {r['per_emotion'][e]:.2f} | {sum(conf[e].values())} | "
                     + " | ".join(str(conf[e].get(k, 0)) for k in heard) + " |" for e in order)
    trusted = f"{r['trusted']:.0%}" if r.get("trusted") is not None else "–"
    return f"""
## Real emotional speech: RAVDESS's held-out actors (test)

What is heard is read off the encoder of Whisper tiny.en (a front end trained by OpenAI on a great deal of real
speech, never on emotion; MIT) by a logistic regression fitted on the synthetic corpus's train takes,
RAVDESS's train actors (18 of 24; calm left out) and, as neutral, sixteen real voices reading without acted
emotion (the Debian packages' telephone prompts and letter readers); its val actors ({RAVDESS_VAL}) chose its regularisation, its
test actors ({RAVDESS_TEST}) were scored once, here. Each actor's clips of one emotion are joined into one
recording and heard window by window as `generate` hears them (10-s windows every 7 s; calm counted as
neutral). **The emotion is heard right in {r['accuracy']:.1%} of {r['windows']} windows** (chance 14 %;
people listening to these clips without video: about 60 %), and `--emotion auto` trusts {trusted} of them.

| emotion | heard right | windows | """ + " | ".join(f"heard as {k}" for k in heard) + """ |
|---|---|---|""" + "---|" * len(heard) + f"""
{rows}

RAVDESS is CC BY-NC-SA 4.0: **these weights are for non-commercial use.** `make model` without `RAVDESS=`
rebuilds a bundle from the synthetic corpus alone.
"""


def real_motion_paragraph(path: Path) -> str:
    """How the model moves on the packaged real read speech (`motion_realism.py`'s report, when there): its
    wrists' speed and how far their speed follows the voice's onsets, against the corpus's."""
    if not path.is_file():
        return ""
    stats = json.loads(path.read_text())
    real, corpus = stats["model, real speech"], stats["corpus"]
    follows = ("follows the voice's onsets" if real["onset_coupling"] >= 0.5 * corpus["onset_coupling"] else
               "follows the voice's onsets only weakly (on a real voice the strokes do not yet land on\n  its syllables "
               "as they do on the corpus's)")
    return (f"- **On a real voice** (the packaged real read speech, `--emotion auto`, seed 0;\n"
            f"  `experiments/reports/motion_realism/`): the wrists move at {real['wrist_speed_mean']:.2f} m/s (the "
            f"corpus's {corpus['wrist_speed_mean']:.2f};\n  people talking about 0.55), and their speed {follows}; "
            f"onset coupling {real['onset_coupling']:.3f},\n  the corpus's {corpus['onset_coupling']:.3f}.\n")


def main(bundle: str, report: str, times: str, cache_dir: str) -> None:
    bundle, report = Path(bundle), Path(report)
    real = json.loads((report / "real" / "real_speech.json").read_text())
    speech = json.loads((report / "speech" / "speech_test.json").read_text())
    gesture = json.loads((report / "gesture" / "gesture_models_test.json").read_text())
    shift = json.loads((report / "perception_shift.json").read_text())
    perception = json.loads((bundle / "speech.json").read_text())["extra"]["emotion_perception"]
    fallback = json.loads((bundle / "gesture.json").read_text())["extra"].get("fallback_style")
    fallback_text = fallback_sentence(fallback)
    semitones = shift.get("perception_semitones", 0)
    shift_how = ("; measured before the front end trained on real speech heard the windows the perception does "
                 f"not trust, each window heard three times, the voice also moved {semitones:g} semitones up and down"
                 if perception.get("heard") and not shift.get("front_end") and semitones else "")
    hearings_text = (" The front end trained on real speech hears the recording as well (one window every 20 s, "
                     "those between interpolated), and the two readings are multiplied: in a window the perception "
                     "trusts fully, the speech model's log-probabilities plus half the front end's, elsewhere the "
                     "front end's plus a quarter of the speech model's; where the trust is low, what the front end "
                     "hears is the emotion animated. The voice is not heard again moved in pitch (that serves models "
                     "without the front end's read-out)." if perception.get("heard") else
                     f" The emotion a window is heard as is the mean of three hearings: as recorded and with the "
                     f"voice moved {semitones:g} semitones up and down (the generation setting "
                     "`perception_semitones`), so a voice pitched unlike the training voices is not read by its "
                     "pitch alone; the trust and the latents animated are the recording's own."
                     if semitones else "")
    if fallback:
        write_text_atomic(report / f"fallback_style_{fallback['split']}.md", fallback_table(fallback))
    rows = gesture["table"]["rows"]
    gt, ours, edit, auto = rows["GT"], rows["ours"], rows["ours, emotion edit"], rows.get("ours, emotion auto")
    metrics = {
        "EA (speech emotion accuracy)": speech["EA"], "SA (speaker accuracy)": speech["SA"],
        "EA, the emotion perception": speech["EA_perceived"],
        "GA (gesture emotion accuracy)": ours["GA"], "GA of the ground truth": gt["GA"],
        "GA, --emotion auto": auto["GA"] if auto else float("nan"), "edit GA (by label)": edit["GA"],
        "FGD": ours["FGD"], "BA": ours["BA"], "BA of the ground truth": gt["BA"],
        "wrist speed (m/s)": ours["Speed"], "wrist speed, ground truth": gt["Speed"],
        "jerk (m/s^3)": ours["Jerk"], "jerk, ground truth": gt["Jerk"],
        "EA, held-out voices": next(iter(shift["rows"].values()))["perceived_correctly"],
        "real speech heard as neutral": real["pooled"]["real"]["heard_share"],
        "real speech windows trusted": real["pooled"]["real"]["trusted_share"],
    }
    # the models' files (not this card, whose size would depend on the card written before it)
    sizes = {p.name: p.stat().st_size for p in sorted(bundle.iterdir())
             if p.suffix in (".json", ".safetensors") and p.name != "card.json"}
    card = {"split": "test", "corpus": "synthetic corpus, 30 speakers, split by text and speaker (seed 0)",
            "metrics": metrics,
            "emotion_perception_thresholds": {k: perception[k]["threshold"] for k in ("emotion", "voice")},
            "sizes_bytes": sizes,
            "training_seconds": Path(times).read_text().strip().splitlines()}
    write_text_atomic(bundle / "card.json", json.dumps(card, indent=1) + "\n")

    shift_rows = "\n".join(
        f"| {name} | {r['perceived_correctly']:.2f} | {r['median_distance_over_threshold']:.2f} | "
        f"{r['median_voice_distance_over_threshold']:.2f} | {r['share_blended_toward_neutral']:.2f} |"
        for name, r in shift["rows"].items())
    total_mb = sum(sizes.values()) / 1e6
    # the version of the corpus the cache was prepared from (that of the code when its marker is missing)
    marker = Path(json.loads((Path(cache_dir) / "manifest.json").read_text())["root"]) / MARKER
    corpus_version = json.loads(marker.read_text())["version"] if marker.is_file() else CORPUS_VERSION
    shares = [r["share_blended_toward_neutral"] for r in shift["rows"].values()]
    blended_orig, blended_lo, blended_hi = shares[0], min(shares[1:]), max(shares[1:])
    stats = gesture["table"]["motion_stats"]
    ours_wrists = [stats["ours"]["angular_speed"][j] for j in ("left_wrist", "right_wrist")]
    gt_wrists = [stats["GT"]["angular_speed"][j] for j in ("left_wrist", "right_wrist")]
    wrist_ratio = float(np.mean(np.divide(ours_wrists, gt_wrists)))
    wrists = " / ".join(f"{v:.3f}" for v in ours_wrists) + " rad/frame, left / right"
    rhythm_text = rhythm_paragraph(rows, gesture["checks"])
    gesture_steps = json.loads((bundle / "gesture.json").read_text())["extra"]["step"]
    heard = Counter(k for r in real["real"].values() for k in r["heard"])
    heard_real = heard_text(heard) + f" of {sum(heard.values())} windows"
    real_voices = perception["info"].get("real_voices", [])
    heard_by = ("synthetic voices only" if not real_voices else
                f"synthetic voices only; its perception's calibration has also heard {len(real_voices)} real voices "
                "(other people's telephone prompts in French, Italian and Russian) given each emotion's prosody, "
                "and reads each emotion by their mean too")
    means_text = ("" if not real_voices else
                  " (each emotion has two means: the training voices' and the real voices', the nearer counting "
                  "most; a window nearer the real voices' mean is animated with the training voices' latent of that "
                  "emotion)")
    readers_text = word_readers_text(report / "word_readers" / "word_readers.json")
    if readers_text:  # the neutral reference's sentence speaks of the same readers
        readers_text += neutral_reference_text(report / "neutral_reference" / "neutral_reference.json")
    conditions = perception["info"].get("condition_means") or (["telephone"] if perception.get("band_labels") else [])
    condition_words = {"telephone": "through a simulated telephone band",
                       "quieter": "{:g}-{:g} dB quieter".format(*QUIETER_DB),
                       "noisy": "in white noise at {:g}-{:g} dB SNR".format(*NOISE_SNR_DB)}
    band_text = ("" if not conditions else
                 f" Each emotion has {len(conditions)} more mean{'s' if len(conditions) > 1 else ''} for the read-out "
                 "alone: of the training takes heard " + ", ".join(condition_words[c] for c in conditions)
                 + ", so that a recording made so is compared with training speech heard the same way (the rows "
                 "below; no real recording of them with a known emotion was at hand to check); it changes what is "
                 "heard, not the trust or the motion.")
    seams_text = seams_paragraph(gesture["checks"])
    real_motion_text = real_motion_paragraph(report.parent / "motion_realism" / "motion_realism.json")
    level_text = level_paragraph(shift["rows"])
    ravdess_text = ravdess_section(report / "ravdess_test.json")
    trained_on = ("the project's **synthetic corpus** and, for the read-out that hears emotion in a real voice (the "
                  "encoder of Whisper tiny.en, MIT, read by a logistic regression), **RAVDESS**'s train actors (below)"
                  if ravdess_text else "the project's **synthetic corpus**")
    text = f"""# Model card: the bundled emogesture model

The model `emogesture generate` uses when no `--model` is given: the `tiny` speech disentanglement
model, the `tiny` gesture generator (motion prior + latent diffusion, joint training) trained on its
latents, and the evaluation suite's motion feature extractor M. Weights are stored in float16
({total_mb:.1f} MB together); configuration and statistics are in the JSON beside each, and
`SHA256SUMS` lists every file's checksum.

## Training data

Trained on {trained_on} (`emogesture corpus --speakers 30`, version {corpus_version}, seed 0):
{corpus_paragraph(Path(cache_dir))}

- speech model: `--losses adversarial`, 1300 steps, half of its windows heard through augmented
  recording conditions (`--set wave_augment=0.5`: rooms, noise, microphones, telephone, voice and
  tempo shifts), then 700 more from there (`--init-from`, learning rate 5e-4) with three quarters of
  its windows augmented, voices moved by up to 6 semitones, the pitch alone moved by up to 3 semitones
  (formants kept) in half of the augmented windows and more level changes, its encoders hearing the
  spectrum up to 4 kHz only (`--set model.heard_bins=96`: real recordings end anywhere from 4 kHz up,
  the synthetic voices never do), **train split only**; each stage's augmented windows made once before
  it, 16 variants of each window (`--set wave_variants=16`);
- extractor M: 600 steps, train split;
- gesture model: joint training, {gesture_steps} steps (450 prior-only first), train split; its residual noise
  and the speech model's emotion perception are calibrated on the **val** split, which no model
  trained on;
- every number below is on the **test** split (held out from all of it), scored once.

Training wall time on 2 CPU cores: {"; ".join(card["training_seconds"])}.

Rebuild from scratch (its trainings alone took {training_minutes(card['training_seconds'])} minutes on 2 cores; making the corpus and scoring add to it):

```bash
{REBUILD}
```

## Numbers on held-out texts and voices (test split)

| measure | value |
|---|---|
| EA / SA (the speech model's classifier heads: emotion / speaker from the audio; SA on the train speakers' windows) | {speech['EA']:.3f} / {speech['SA']:.3f} |
| EA of the emotion perception, each prepared window heard once (the emotion head, and the nearest emotion mean where the window lies within the calibrated range; `generate` as it hears: the table below) | {metrics['EA, the emotion perception']:.3f} |
| the same on the voices it never heard (the test speakers' windows) | {metrics['EA, held-out voices']:.3f} |
| GA: the generated motion's emotion, read by the extractor (ground truth: {gt['GA']:.3f}) | {ours['GA']:.3f} |
| GA with `--emotion auto` (the default of `generate`) | {metrics['GA, --emotion auto']:.3f} |
| edit GA: motion re-generated with another emotion's label, read as that emotion | {edit['GA']:.3f} |
| FGD (lower is better) | {ours['FGD']:.2f} |
| BA (ground truth {gt['BA']:.3f}; on this corpus BA hardly tells matched from mismatched audio) | {ours['BA']:.3f} |
| wrist speed, m/s (ground truth) | {ours['Speed']:.3f} ({gt['Speed']:.3f}) |
| jerk, m/s³ (ground truth) | {ours['Jerk']:.1f} ({gt['Jerk']:.1f}) |

The full reports: `experiments/reports/bundled_model/` in the source repository.
{ravdess_text}
## Limits, in plain words

- **Real voices lie outside its training data.** Its weights have heard {heard_by}. On real read
  speech (Debian's `pocketsphinx-testdata`: a LibriVox reader, a man reading card names, three CMU
  test utterances; and `asterisk-core-sounds-en-g722`: a professional voice reading telephone-system
  prompts; `emogesture evaluate real`) beside the test split's neutral takes:

| real read speech | real | held-out corpus takes |
|---|---|---|
{real_rows(real)}

  So the emotion it perceives in your voice may be wrong (these real recordings, all read without
  acted emotion, are heard as {heard_real}), and set it yourself where it matters. Recording by
  recording: {real_recording_text(real)}. A window `--emotion auto` trusts is one whose speech lies
  within the range of the training speech, not one whose emotion is right: a trusted window is animated
  with the emotion heard, right or wrong, where the windows beyond the range are animated as neutral.{readers_text}
- **What `generate` does about it.** It prints the emotion it perceives (majority over 10-s windows,
  with its mean probability) and writes every window's perception to `*_perception.json`. A window's
  emotion is read by the speech model's classifier and, where the window's emotion latent lies near an
  emotion the model knows, by the nearest emotion mean as well{means_text}; elsewhere by the classifier
  alone. With
  `--emotion auto` (the default) it trusts a window's emotion only where the speech lies within the
  range of the training speech: the window's emotion latent near an emotion the model knows, and its
  style latent (the voice) near one of the training speakers. Each is a Mahalanobis distance to the
  nearest mean, against a threshold set at the {perception['info']['quantile']:g} quantile of the
  distances of held-out val windows. Beyond a threshold the window's emotion is blended toward the
  neutral mean, fully at twice the threshold, and a voice unlike every training voice has its gesture
  style blended toward a fallback style, so that the motion stays like the motion the model learned;
  the message says so. {fallback_text} A recording in steady background noise (its loud and quiet
  frames less than 20 dB apart) is heard with that noise subtracted first, in proportion to how noisy it
  is (the generation setting `noise_suppression`; the white-noise row below). Digital silence (exact zeros:
  clips joined with inserted silence, a noise gate, padding), which no training recording has, is heard
  as the recording's own quiet.{hearings_text}{band_text} `--emotion own` keeps the raw
  perception; `--emotion LABEL` or `--emotion-from WAV` sets the emotion yourself, which is the
  reliable way on real speech.
- **How the perception behaves away from the training voices** (held-out takes changed on purpose;
  distances in units of their thresholds; `experiments/reports/bundled_model/perception_shift.md`{shift_how}):

| audio | perceived emotion correct | median emotion distance | median voice distance | share blended toward neutral |
|---|---|---|---|---|
{shift_rows}

  Changed voices are misheard, and it is mostly the voice distance that notices (the emotion
  latent alone often looks familiar): `auto` blends {blended_lo:.0%} to {blended_hi:.0%} of the
  windows of the changed recordings toward neutral, and {blended_orig:.1%} of the unchanged ones.
{level_text}
{rhythm_text}
{seams_text}
{real_motion_text}- **Motion.** The gestures are those of a procedural corpus: upper body and fingers (the legs stay at rest;
  the face comes from `--face`, not from this model); the body turns and leans but does not travel. Since corpus version 3 the training motion turns at speeds within
  the range of real conversational motion capture, joint by joint. This model's hands move at
  {ours['Speed']:.2f} m/s (the ground truth's {gt['Speed']:.2f}), and its wrists turn at {wrist_ratio:.0%} of the
  ground truth's angular speed ({wrists}; two real BEAT takes: 0.023–0.038 / 0.032–0.041;
  `emogesture motion-stats`; the tables are in `experiments/corpus/README.md`).
  The gestures are generic beats and reaches, not the meaningful (iconic, deictic) gestures people make.
- **Speakers.** `--style-from` can only take styles like the ones it knows (its train speakers'); another
  voice gives a style somewhere between them.
"""
    write_text_atomic(bundle / "MODEL_CARD.md", text)
    write_checksums(bundle)
    print(text)


if __name__ == "__main__":
    main(*sys.argv[1:5])
