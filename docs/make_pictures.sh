#!/bin/sh
# Regenerate the README's pictures (run from the repository root: `make pictures`).
#   docs/fig5_phototaxis.png  the paper's Fig. 5 reproduced (kilobot-twin experiment phototaxis --quick)
#   docs/viewer_demo.png      the Rerun viewer on the demo's recording (out/demo/latest/twin.rrd)
# Needs a display for the viewer; without one it uses xvfb-run (a screen larger than the window, so
# that the pointer, at its centre, hovers over nothing) and software Vulkan:
#   apt-get update && apt-get install -y xvfb mesa-vulkan-drivers
# The viewer picture uses the latest finished `make demo` run (a quick demo is run if there is none).
set -eu
BIN=${BIN:-.venv/bin}
OUT=${OUT:-out/pictures}
mkdir -p "$OUT" docs

shrink() {  # SRC DST: 1100 px wide, 256 colours (small PNGs for the README)
    "$BIN/python" - "$1" "$2" 1100 <<'PY'
import sys
from PIL import Image
src, dst, width = sys.argv[1], sys.argv[2], int(sys.argv[3])
im = Image.open(src).convert("RGB")
im = im.resize((width, round(im.height * width / im.width)), Image.LANCZOS)
im.quantize(colors=256, method=Image.MEDIANCUT, dither=Image.NONE).save(dst, optimize=True)
print(dst)
PY
}

# 1. Fig. 5: phototaxis cost vs heading bias (41 robots x 20 runs per P_R, seed 2023).
"$BIN/kilobot-twin" experiment phototaxis --quick --out "$OUT/phototaxis" --no-progress >/dev/null
shrink "$OUT/phototaxis/fig5_phototaxis.png" docs/fig5_phototaxis.png

# 2. The viewer on the demo recording (arena in metres, light readings, metrics, traits).
RRD=out/demo/latest/twin.rrd
if [ ! -f "$RRD" ]; then
    "$BIN/kilobot-twin" demo --quick --out out/demo --no-progress >/dev/null
fi
SHOT="$OUT/viewer_full.png"
if [ -n "${DISPLAY:-}" ]; then
    "$BIN/rerun" "$RRD" --screenshot-to "$SHOT" --window-size 1600x1000
else
    xvfb-run -a -s "-screen 0 4000x2400x24" "$BIN/rerun" "$RRD" --screenshot-to "$SHOT" --window-size 1600x1000
fi
shrink "$SHOT" docs/viewer_demo.png
ls -l docs/fig5_phototaxis.png docs/viewer_demo.png
