# Shared by the experiment scripts (sourced, from the repository root): the command, the work folder,
# and the default synthetic corpus with its windows cache (built or completed when missing; both resume).
EG=.venv/bin/emogesture
WORK=outputs/experiments
CACHE=outputs/demo/cache
$EG corpus --out outputs/demo/corpus --resume --quiet
$EG prepare outputs/demo/corpus --out "$CACHE" --quiet
