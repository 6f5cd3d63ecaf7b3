#!/usr/bin/env bash
# The pictures the README and docs/data.md show, from the bundled model as installed (run after `make model`):
#   docs/demo.png: a frame at 12.5 s of `make demo`'s first video (the shipped speech clip, seed 0);
#   experiments/corpus/reports/contact_sheet.png: a pose every second (2–7 s) of test take 2_scott_0_4_4,
#     corpus version 6 against version 5 (the same speech) and the bundled model's animation of the same
#     speech (hands, body turn and gesture space of each).
# Both are replaced. Usage: experiments/docs_images/docs_images.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
source experiments/common.sh  # the experiments' corpus (version 6), built when missing
OUT=outputs/docs_images
TAKE=2_scott_0_4_4
V5=outputs/demo/corpus_v5
mkdir -p "$OUT"
if [ ! -f "$V5/smplxflame_30/$TAKE.npz" ]; then  # corpus v5 is built by the code of its day: the last commit before v6
    CODE=outputs/corpus_v5_code
    [ -d "$CODE" ] || git worktree add --detach -f "$CODE" 45fce84
    PYTHONPATH="$CODE/src" .venv/bin/python -c 'import sys; from emogesture.cli.main import main; sys.exit(main())' \
        corpus --out "$V5" --resume --quiet
fi
$EG generate src/emogesture/assets/demo/talk.flac -o "$OUT" --format mp4 --overwrite --quiet
ffmpeg -loglevel error -y -ss 12.5 -i "$OUT/talk_seed0_0.mp4" -frames:v 1 "$OUT/demo.png"
mv "$OUT/demo.png" docs/demo.png
$EG generate "$CORPUS/wave16k/$TAKE.wav" -o "$OUT" --format npz --overwrite --quiet
.venv/bin/python experiments/docs_images/contact_sheet.py experiments/corpus/reports/contact_sheet.png --overwrite \
    "corpus v6\n(now)=$CORPUS/smplxflame_30/$TAKE.npz" \
    "corpus v5\n(before)=$V5/smplxflame_30/$TAKE.npz" \
    "generated\n(bundled model,\ntrained on v6)=$OUT/${TAKE}_seed0_0.npz"
