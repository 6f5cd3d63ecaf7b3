# Shared by the experiment scripts (sourced, from the repository root): the command, the work folder,
# and the experiments' synthetic corpus with its windows cache (built or completed when missing; both resume):
# all 30 voices, split by text and by speaker together (the val and test actors' voices never heard in training).
EG=.venv/bin/emogesture
WORK=outputs/experiments
CORPUS=$WORK/corpus30
CACHE=$WORK/cache30
$EG corpus --out "$CORPUS" --speakers 30 --resume --quiet
$EG prepare "$CORPUS" --out "$CACHE" --set split_source=csv+actor --quiet
# The tiny preset's generation settings (GenerationConfig.preset; since 2026-11-26: guidance 6 on the onsets,
# low-pass 4 Hz, half the calibrated residual noise, 10 DDIM steps), for gesture runs trained before they last
# changed: `emogesture bundle --set` applies them, no retraining.
GENERATION=(--set timing_guidance=6 --set timing_guidance_on=onsets --set output_lowpass_hz=4
            --set num_inference_steps=10 --set residual_scale=0.5)
