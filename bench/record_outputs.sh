#!/usr/bin/env bash
# Record a fixed set of osmap outputs, messages and help texts, to show that a refactor changes
# no byte: run it before and after, then compare (sums.txt: every output file; log.txt: what each
# run printed, timings masked; help.txt: every --help and the default presets).
#
#   bash bench/record_outputs.sh "$PWD" /tmp/before   # on the old commit
#   bash bench/record_outputs.sh "$PWD" /tmp/after    # on the new one
#   diff /tmp/before/sums.txt /tmp/after/sums.txt && diff /tmp/before/log.txt /tmp/after/log.txt
#
# Covers synth (default, tileable, fields, --with, --uv-out, EXR, TIFF, JPEG, RGBA with
# scale/orientation, paper, a preset with flags, a batch), apply, info, solid in every format
# (npy + uv + preview, PNG and EXR slices, atlas, NRRD raw and gzip, per-axis, a batch),
# surface (OBJ + report, PLY + preview) and three errors. REPO must have its .venv.
set -u
repo=$1; out=$2
O="$repo/.venv/bin/osmap"
S=$repo/samples
rm -rf "$out"; mkdir -p "$out/f"; cd "$out/f"
export NUMBA_NUM_THREADS=2
"$repo/.venv/bin/python" - <<'PY'
import numpy as np, OpenImageIO as oiio
y, x = np.mgrid[0:64, 0:64] / 63.0
for name, arr in (("orient.png", x), ("scalef.png", 0.3 + 0.4 * y)):
    out = oiio.ImageOutput.create(name); out.open(name, oiio.ImageSpec(64, 64, 1, "uint8")); out.write_image((arr * 255).astype(np.uint8)); out.close()
PY
cp $S/cells.png ex.png; cp $S/brick.png rough.png
run() { echo "\$ $*" >> ../log.txt; "$@" >> ../log.txt 2>&1; echo "exit $?" >> ../log.txt; }
run $O synth ex.png -o s_default.png --size 64
run $O synth ex.png -o s_tile.png --size 64 --tileable
run $O synth ex.png -o s_fields.png --size 64 --orientation-field orient.png --scale-field scalef.png
run $O synth ex.png -o s_with.png --size 64 --with rough=rough.png --with normal=$S/weave.png --uv-out s_uv.exr
run $O synth ex.png -o s_exr.exr --size 48 --bit-depth 32
run $O synth ex.png -o s_16.tif --size 48 --bit-depth 16
run $O synth ex.png -o s_j.jpg --size 48
run $O synth $S/cells_rgba.png -o s_rgba.png --size 48 --scale 1.5 --orientation 20 --anisotropy 1.2
run $O synth ex.png -o s_paper.png --size 32 --method paper
run $O synth ex.png -o s_pre.png --size 48 --preset stochastic --quality fast --levels 3 --seed 5
mkdir b; run $O synth ex.png rough.png --out-dir b --name '{stem}_{index}.png' --size 32 --json
run $O apply s_uv.exr rough.png -o s_apply.png
run $O info s_default.png
run $O info s_with_rough.png --json
run $O info s_uv.exr --command
run $O solid ex.png -o v.npy --size 16 --uv-out v_uv.npy --preview v_prev.png
run $O solid ex.png -o v_slices --size 16
run $O solid ex.png -o v_exr --size 16 --format exr
run $O solid ex.png -o v_4x4.png --size 16
run $O solid ex.png -o v.nrrd --size 16 --nrrd-encoding gzip --preset structured --quality fast
run $O solid ex.png -o v_raw.nrrd --size 16 --tileable --seed 3
run $O solid --x ex.png --y $S/weave.png --z ex.png -o v_axes.npy --size 16
run $O info v_4x4.png
mkdir vb; run $O solid ex.png rough.png --out-dir vb --size 16 --format nrrd --json
run $O surface --shape torus -o t.obj --grid 16x16 --report
run $O surface --shape roll -o r.ply --grid 16x16 --vary x=u,y=u,z=v --preview r.png
run $O synth nope.png -o x.png
run $O synth ex.png -o x.png --scale 100
run $O solid ex.png -o x.npy --size 4
cd ..
for c in "" synth solid apply info surface presets "presets list" "presets show default" "presets show structured"; do
  echo "=== osmap $c" >> help.txt; $O $c --help >> help.txt 2>&1 || true
done
$O presets >> help.txt; $O presets show default >> help.txt
sed -i -E 's/\([0-9]+\.[0-9] s\)/(T s)/g; s/"seconds": [0-9.]+/"seconds": T/g' log.txt
(cd f && find . -type f | sort | xargs sha256sum) > sums.txt
