#!/usr/bin/env bash
# Side-by-side of posereg and elastix on the same pairs, same machine, same threads.
#   scripts/compare_elastix.sh [OUT_DIR]      (default ./compare-elastix; DEVICES="cpu gpu", THREADS=2)
# Pairs: the half-size phantom bent 10° and 60° (2% noise, 15% bias), each registered straight
# → bent. elastix runs affine + multi-resolution B-spline (scripts/elastix/*.txt); its field comes
# from transformix (-def all), which is in the same ITK convention as posereg's field.nii.gz, so
# both are scored by `posereg eval` against the phantom's truth over the target's body.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-compare-elastix}"
threads="${THREADS:-2}"
command -v elastix >/dev/null || {
    sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get install -y -qq elastix
}
cargo build --release -q
bin=target/release/posereg
mkdir -p "$out"
seconds() { /usr/bin/time -f %e "$@" 2>&1 >/dev/null | tail -1; }
printf '| pair | method | wall s | mean error mm | within 2 vox | within 4 vox | correlation |\n|---|---|---|---|---|---|---|\n' > "$out/table.md"
for deg in 10 60; do
    pair="$out/pair$deg"
    $bin phantom --size half -o "$pair/straight" --seed 1 >/dev/null
    $bin phantom --size half --flexion "$deg" -o "$pair/bent" --seed 2 >/dev/null
    score() { # method, field, warped
        local json
        json=$($bin eval --field "$2" --truth "$pair/bent/truth_field.nii.gz" --mask "$pair/bent/labels.nii.gz" \
            --warped "$3" --target "$pair/bent/image.nii.gz" --json)
        python3 - "$json" "$deg" "$1" "$4" >> "$out/table.md" <<'PY'
import json, sys
v = json.loads(sys.argv[1])
print(f"| half phantom {sys.argv[2]}° | {sys.argv[3]} | {float(sys.argv[4]):.1f} | {v['mean_mm']:.2f} | "
      f"{100 * v['within_2_voxels']:.1f}% | {100 * v['within_4_voxels']:.1f}% | {v['correlation']:.3f} |")
PY
    }
    for device in ${DEVICES:-cpu gpu}; do
        t=$(seconds $bin register --device "$device" --source "$pair/straight/image.nii.gz" \
            --source-labels "$pair/straight/labels.nii.gz" --target "$pair/bent/image.nii.gz" -o "$pair/posereg-$device")
        score "posereg ($device$( [ $device = gpu ] && echo ', lavapipe'))" "$pair/posereg-$device/field.nii.gz" "$pair/posereg-$device/warped.nii.gz" "$t"
    done
    mkdir -p "$pair/elastix"
    t=$(seconds elastix -f "$pair/bent/image.nii.gz" -m "$pair/straight/image.nii.gz" \
        -p scripts/elastix/affine.txt -p scripts/elastix/bspline.txt -out "$pair/elastix" -threads "$threads")
    transformix -def all -tp "$pair/elastix/TransformParameters.1.txt" -out "$pair/elastix" -threads "$threads" >/dev/null
    score "elastix affine + B-spline" "$pair/elastix/deformationField.nii" "$pair/elastix/result.1.nii" "$t"
done
cat "$out/table.md"
