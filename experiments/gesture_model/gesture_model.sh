#!/usr/bin/env bash
# The tiny gesture model (joint training, the paper's model) against its three ablations (disjoint
# training, no motion prior, no audio disentanglement) on the default synthetic corpus, on this CPU.
# "Ours" is the model shipped in the package (src/emogesture/assets/model/, built by
# experiments/bundled_model.sh = `make model`, float16 weights as shipped): its speech model trained
# on the train texts only, its extractor M, its gesture model. The ablations train here on that same
# speech model, train texts only; every model's residual noise is calibrated on val.
# Comparisons are made on the val split (calibrated on, never trained on); the test split is scored
# once, for the report (paper Table 1 layout plus the prior's reconstruction error, emotion edits and a
# 65-s long-audio seam check, each check able to fail).
# "Ours without the stream" is the tiny design before its decoder heard the speech's timing (48 cosines,
# the decoder deaf to timing, no wrist path).
# Four trainings side by side, one CPU thread each (about 60 min on 2 cores), then the evaluations:
# val with 4 sampling seeds, test once.
# Writes experiments/gesture_model/reports/gesture_model/{val,test}/, val_seeds.md and training_time.txt.
# Usage: experiments/gesture_model/gesture_model.sh [STEPS] [JOINT_STEPS]   (defaults: 900 1200)
# No prior and no audio train STEPS; disjoint trains JOINT_STEPS (half prior, half denoiser), like ours.
set -euo pipefail
cd "$(dirname "$0")/../.."
STEPS=${1:-900}
JOINT_STEPS=${2:-1200}
source experiments/common.sh
REPORT=experiments/gesture_model/reports/gesture_model
BUNDLE=src/emogesture/assets/model
SPEECH=$BUNDLE/speech.json
mkdir -p "$REPORT"

sha_of() {  # key model.json -> the SHA256 under that key (nothing when absent)
    grep -so "\"$1\": \"[0-9a-f]*\"" "$2" | head -1 | grep -o '[0-9a-f]\{64\}' || true
}
SPEECH_SHA=$(sha_of weights_sha256 "$SPEECH")
train() {  # name variant steps [--set ...] -> trains into $WORK/gesture_<name> on one thread, writes its wall time
    local name=$1 variant=$2 steps=$3 start resumed="" old
    shift 3
    # a run (finished or not) on another speech model, e.g. before `make model` rebuilt the bundle, is
    # moved aside, not resumed
    old=$(sha_of speech_weights_sha256 "$WORK/gesture_$name/model.json")  # none for no_audio
    if [ -n "$old" ] && [ "$old" != "$SPEECH_SHA" ]; then
        echo "gesture_$name was trained on another speech model; moved to gesture_$name.speech-${old:0:8}"
        mv "$WORK/gesture_$name" "$WORK/gesture_$name.speech-${old:0:8}"
    fi
    grep -qs "\"step\": $steps" "$WORK/gesture_$name/model.json" && return 0
    [ -f "$WORK/gesture_$name/checkpoints/last.ckpt" ] && resumed=", resumed from a checkpoint: the time of the resumed part"
    start=$(date +%s)
    OMP_NUM_THREADS=1 $EG train gesture --variant "$variant" --data "$CACHE" --speech "$SPEECH" \
        --out "$WORK/gesture_$name" --steps "$steps" --checkpoint-every 100 --quiet \
        --set "disjoint_prior_steps=$((steps / 2))" "$@"
    echo "$name: $(( $(date +%s) - start )) s for $steps steps (1 thread, beside other trainings$resumed)" \
        > "$WORK/gesture_$name.time"
}
# "ours without the stream": the tiny design before the timing stream, 48 cosines, no timing stream, no wrist path
train disjoint disjoint "$JOINT_STEPS" & train no_prior no_prior "$STEPS" & train no_audio no_audio "$STEPS" &
train no_stream joint "$JOINT_STEPS" --set model.vae.low_frequency_path=48 --set model.vae.timing_features=0 \
    --set model.vae.timing_smoothing=0 --set generation.timing_guidance=1 --set generation.output_smoothing=0 \
    --set generation.output_lowpass_hz=0 --set model.vae.detail_path=0 --set "model.vae.detail_columns=[]" &
wait
{ grep '^gesture' experiments/reports/bundled_model/training_time.txt | sed 's/^gesture/joint (ours, the bundled model)/'
  for f in "$WORK"/gesture_{no_stream,disjoint,no_prior,no_audio}.time; do if [ -f "$f" ]; then cat "$f"; fi; done
} | tee "$REPORT/training_time.txt"

# disjoint hears the stream as ours does: scored with the same generation settings (common.sh), float16 as ours
$EG bundle --speech "$SPEECH" --gesture "$WORK/gesture_disjoint" --out "$WORK/gesture_disjoint_bundle" --overwrite \
    "${GENERATION[@]}" > /dev/null
MODELS=(--model "ours=$BUNDLE/gesture.json" --model "ours without the stream=$WORK/gesture_no_stream"
        --model "disjoint=$WORK/gesture_disjoint_bundle/gesture.json"
        --model "no prior=$WORK/gesture_no_prior" --model "no audio model=$WORK/gesture_no_audio")
for split in val test; do
    $EG evaluate gesture --data "$CACHE" --extractor "$BUNDLE/extractor.json" --split "$split" \
        --out "$REPORT/$split" --overwrite "${MODELS[@]}"
done
# three more sampling seeds on val (no long audio): the seed spread of every row
for seed in 1 2 3; do
    $EG evaluate gesture --data "$CACHE" --extractor "$BUNDLE/extractor.json" --split val --seed "$seed" \
        --long-audio 0 --out "$WORK/gesture_model_val_seed$seed" --overwrite "${MODELS[@]}"
done
.venv/bin/python experiments/gesture_model/seed_summary.py "$REPORT/val/gesture_models_val.json" \
    "$WORK"/gesture_model_val_seed{1,2,3}/gesture_models_val.json > "$REPORT/val_seeds.md"
