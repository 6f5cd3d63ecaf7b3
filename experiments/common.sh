# Shared by the experiment scripts (sourced, from the repository root): the command, the work folder,
# and the default synthetic corpus with its windows cache (built or completed when missing; both resume).
EG=.venv/bin/emogesture
WORK=outputs/experiments
CACHE=outputs/demo/cache
$EG corpus --out outputs/demo/corpus --resume --quiet
$EG prepare outputs/demo/corpus --out "$CACHE" --quiet
# The tiny preset's generation settings (GestureModelConfig.preset; session 23: guidance 3.5, low-pass 3 Hz, 10 DDIM steps), for
# gesture runs trained before they last changed: `emogesture bundle --set` applies them, no retraining.
GENERATION=(--set vae.timing_guidance=3.5 --set vae.output_lowpass_hz=3 --set diffusion.num_inference_steps=10)
