# The bundled model's recipe, for the experiment scripts (sourced, from the repository root, after common.sh).
# The recipe itself is configs/bundled.yaml: `train_bundle RUN CACHE` builds it into RUN (RUN/bundle: float16
# weights, config and statistics in JSON, SHA256SUMS) with `emogesture train bundle`, every step resumed when
# re-run, each training's wall time appended to RUN/times.txt; bundled_model.sh runs it on the experiments'
# corpus and ships the result (ship_bundle). The arrays below are the recipe's stage settings as `--set`
# options, for the experiments that train one stage with one of them changed (the recipe test checks they
# agree with configs/bundled.yaml).

# the second speech stage's harder conditions and learning rate
SPEECH_HARD=(--set wave_augment=0.75 --set wave.voice=0.6 --set wave.voice_semitones=6 --set wave.loudness=0.6
             --set lr=5e-4 --set lr_decay_start=100)
# the studio voices of emogesture.data.real_speech.TRAINING_VOICES, real people reading without acted emotion:
# the perception's calibration gives each emotion a mean of theirs too (4.)
REAL_VOICES="fr_june, it_carlo, ru_ivr"
# the recipe's perception calibration (4.): those voices' means, and each emotion's means of the train takes heard
# through a telephone band (telephone_means.sh), quieter and in noise (condition_means.sh) for the read-out
PERCEPTION=(--real-voices "$REAL_VOICES" --condition-means telephone,quieter,noisy)
# both speech stages: each training window's augmented recordings made once, 16 variants (wave_variants.sh),
# every window at its own recording level (±10 dB)
SPEECH_VARIANTS=(--set wave_variants=16 --set level_jitter_db=10)
# the second stage: the pitch alone moved too (pitch_alone.sh), formants kept, as people's pitch differs
# around their vocal tracts more than the corpus's speakers' does
SPEECH_PITCH=(--set wave.pitch=0.5 --set wave.pitch_semitones=3)
# the second stage: its encoders hear the mel bins up to 4 kHz only (heard_bins.sh), as real recordings end
# anywhere from 4 kHz up (codecs, microphones) and the synthetic voices never do
SPEECH_BAND=(--set model.heard_bins=96)

speech_more() {  # NAME THREADS [--set ...] : 500 speech steps more into $RUN/NAME with the caller's STAGE
    # arguments (an array: data, starting model, settings), unless done; its wall time to $RUN/times.txt
    local name=$1 threads=$2 start
    shift 2
    grep -qs '"step": 500' "$RUN/$name/model.json" && return
    start=$(date +%s)
    OMP_NUM_THREADS=$threads $EG train speech --out "$RUN/$name" "${STAGE[@]}" "$@"
    echo "$name: $(( $(date +%s) - start )) s (OMP_NUM_THREADS=$threads)" >> "$RUN/times.txt"
}

speech_calibrated() {  # NAME MODEL [--real-voices ...] : MODEL's emotion perception calibrated on $CACHE's val
    # into $RUN/NAME, unless it is there
    local name=$1 model=$2
    shift 2
    [ -f "$RUN/$name/model.json" ] || $EG calibrate speech --model "$model" --data "$CACHE" --out "$RUN/$name" "$@"
}

perception_val() {  # NAME... : perception_shift.py on val for each calibrated speech model $RUN/NAME into
    # $REPORT/perception_NAME, unless its report is there
    local name
    for name in "$@"; do
        [ -f "$REPORT/perception_$name/perception_shift.md" ] || \
            .venv/bin/python experiments/perception_shift.py "$RUN/$name" "$CACHE" "$REPORT/perception_$name" val
    done
}

real_reports() {  # NAME=SPEECH_MODEL... : the real recordings at three gains (real_perception.py) and given each
    # emotion's prosody (real_voice_emotions.py), per model, into $REPORT; $RUN's training times beside them
    .venv/bin/python experiments/real_perception.py "$REPORT/real" "$@"
    .venv/bin/python experiments/real_voice_emotions.py "$REPORT/real_voice_emotions" "$@"
    cp "$RUN/times.txt" "$REPORT/training_time.txt"
}

timed() {  # times.txt name command... : runs a training step and appends its wall time to times.txt
    local times=$1 name=$2 start
    shift 2
    start=$(date +%s)
    "$@"
    echo "$name: $(( $(date +%s) - start )) s" >> "$times"
}

train_gesture() {  # OUT CACHE SPEECH TIMES NAME : the recipe's gesture model (3600 steps), unless OUT has it
    local out=$1 cache=$2 speech=$3 times=$4 name=$5
    grep -qs '"step": 3600' "$out/model.json" || timed "$times" "$name" $EG train gesture --data "$cache" \
        --speech "$speech" --out "$out" --steps 3600 --checkpoint-every 200 --quiet
}

speech_second_stage() {  # OUT FIRST CACHE TIMES [option ...] : the recipe's second speech stage, 700 steps on
    # from the first stage FIRST, into OUT unless it is there; its wall time to TIMES
    local out=$1 first=$2 cache=$3 times=$4
    shift 4
    grep -qs '"step": 700' "$out/model.json" || timed "$times" speech_tuned $EG train speech --data "$cache" \
        --init-from "$first" --out "$out" --losses adversarial --steps 700 --checkpoint-every 100 \
        "${SPEECH_HARD[@]}" "${SPEECH_PITCH[@]}" "${SPEECH_BAND[@]}" "${SPEECH_VARIANTS[@]}" "$@" --quiet
}

# RAVDESS (24 actors, CC BY-NC-SA 4.0: a bundle trained on it is for non-commercial use), when the user gives its
# audio_speech_actors_01-24 folder as RAVDESS=...: split by actor, both sexes in val and test (the split of
# experiments/ravdess/, where the choices were made on val), calm left out of training
RAVDESS_SPLIT=(--val-speakers actor02,actor03,actor12 --test-speakers actor08,actor17,actor19)

ravdess_manifest() {  # OUT : the labelled-speech manifest of $RAVDESS, unless OUT is there
    [ -f "$1" ] || $EG labelled-speech ravdess "$RAVDESS" --out "$1" "${RAVDESS_SPLIT[@]}" --calm drop
}

ravdess_scoring_manifest() {  # OUT : the manifest the val and test actors are scored on (calm as neutral)
    [ -f "$1" ] || $EG labelled-speech ravdess "$RAVDESS" --out "$1" "${RAVDESS_SPLIT[@]}" --calm neutral
}

train_bundle() {  # RUN CACHE : the bundled model's recipe (configs/bundled.yaml) trained, calibrated and bundled
    # into RUN/bundle by `emogesture train bundle` (with RAVDESS when RAVDESS=... is given), every step resumed
    $EG train bundle --recipe configs/bundled.yaml --data "$2" --out "$1" ${RAVDESS:+--labelled-root "$RAVDESS"} --quiet
}

ship_bundle() {  # BUNDLE REPORT TIMES : 6. the bundle, as shipped (float16), scored once on the test texts
    # (speech and gesture reports, the perception on changed voices, real recorded speech against the test
    # takes of the same emotion), its model card written from those numbers and TIMES (its trainings' wall
    # times), then copied into the package
    local bundle=$1 report=$2 times=$3 assets=src/emogesture/assets/model
    mkdir -p "$report"
    $EG evaluate speech "$bundle/speech.json" --data "$CACHE" --split test --out "$report/speech" --overwrite
    $EG evaluate gesture --data "$CACHE" --extractor "$bundle/extractor.json" --split test --out "$report/gesture" \
        --overwrite --model "ours=$bundle/gesture.json"
    .venv/bin/python experiments/perception_shift.py "$bundle/speech.json" "$CACHE" "$report"
    $EG evaluate real --data "$CACHE" --model "$bundle/gesture.json" --out "$report/real" --overwrite
    [ "$times" -ef "$report/training_time.txt" ] || cp "$times" "$report/training_time.txt"
    if [ -n "${RAVDESS:-}" ]; then  # RAVDESS's test actors, scored once (calm counted as neutral)
        [ -f "$report/ravdess_test.json" ] || { ravdess_scoring_manifest "$WORK/ravdess_scored.csv" && \
            .venv/bin/python experiments/ravdess/perception_val.py "$bundle/speech.json" "$WORK/ravdess_scored.csv" \
                test "$report/ravdess_test.json"; }
    fi
    .venv/bin/python experiments/model_card.py "$bundle" "$report" "$times" "$CACHE"
    mkdir -p "$assets"
    rm -f "$assets"/*
    cp "$bundle"/{speech,gesture,extractor}.{json,safetensors} "$bundle"/{MODEL_CARD.md,card.json,SHA256SUMS} "$assets/"
    $EG model-info
}
