#!/usr/bin/env bash
# Side-by-side of posereg and elastix on the same pairs, same machine, same threads.
#   scripts/compare_elastix.sh [OUT_DIR]      (default ./compare-elastix; DEVICES="cpu gpu", THREADS=2,
#                                               PAIRS="phantom10 phantom60 knee10")
# Pairs, each registered straight → bent:
#   phantom10, phantom60   the half-size phantom (68×128×128) bent 10° and 60° (2% noise, 15% bias),
#                          posereg with its initialisation;
#   knee10                 the real knee of ../shared/data/knee-dess averaged 2×2 in-plane
#                          (256×256×80 at 0.625×0.625×1.5 mm, by SimpleITK's BinShrink; labels by
#                          nearest neighbour) and bent 10° by `posereg bend` (the paper's synthetic
#                          experiment), posereg with and without its initialisation;
#   paper-phantom10        the paper's experiment at the scale the paper registered at: the quarter
#                          phantom (34×64×64, 5 mm voxels) bent 10°, posereg without initialisation;
#   paper-knee10           the same on the real knee averaged 8×8×2 (64×64×40 at 2.5×2.5×3 mm).
#   indep{2,1}-{20,45,90}  the real knee bent 20°, 45°, 90° by scripts/make_pair.py (independent of
#                          posereg: its own axis, motions and soft-tissue flow, per-scan bias and
#                          noise) at 2 mm and 1 mm voxels; indep2-fibula: 20° at 2 mm with the
#                          target cut below (the fibula mostly out of view);
#   indep{2,1}-{20,45,90}v the same bends and seeds with volume-keeping soft tissue
#                          (make_pair.py --tissue incompressible: the flow made divergence-free,
#                          plus a curl-noise wobble); indep{2,1}-{20,45,90}f the same with the air
#                          free (--air free: only the body keeps its volume, the skin bulges; the
#                          v pairs' projection keeps the air's volume too, and what the bend pushes
#                          out circulates through the whole box). MAKE_PAIR_OPTS adds make_pair.py options to
#                          every independent pair made (a pair already in OUT_DIR/NAME/pair is
#                          reused as it is). Scored by scripts/score_pair.py (body, bone, soft
#                          tissue split by whether the truth keeps its volume, the warped source's
#                          correlation with the target, folds, worst bone) in
#                          OUT_DIR/independent.md, with SimpleITK demons (scripts/demons.py) and
#                          PICSL greedy (scripts/greedy.py, pip install picsl-greedy) beside
#                          elastix; elastix uses mutual information there (scans shaded differently).
# SKIP_POSEREG=1 runs the peers only (no cargo build, no posereg runs).
# elastix runs affine + multi-resolution B-spline
# (scripts/elastix/*.txt); its field comes from transformix (-def all), which is in the same ITK
# convention as posereg's field.nii.gz, so both are scored by `posereg eval` against the truth
# field (phantoms: over the target's body; the knee: over every voxel, the scan has no background
# to leave out).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-compare-elastix}"
threads="${THREADS:-2}"
command -v elastix >/dev/null || {
    sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get install -y -qq elastix
}
skip_posereg=${SKIP_POSEREG:-0}
[ "$skip_posereg" = 1 ] || cargo build --release -q
bin=target/release/posereg
mkdir -p "$out"
seconds() { /usr/bin/time -f %e "$@" 2>&1 >/dev/null | tail -1; }
[ "$skip_posereg" = 1 ] || printf '| pair | method | wall s | mean error mm | within 2 vox | within 4 vox | correlation |\n|---|---|---|---|---|---|---|\n' > "$out/table.md"

# compare DIR NAME SOURCE LABELS TARGET TRUTH MASK(or "") [posereg runs: "label|flags" ...]
# (DIR without spaces: elastix cannot write into folders with spaces in their names)
compare() {
    local dir=$1 name=$2 source=$3 labels=$4 target=$5 truth=$6 mask=$7
    shift 7
    score() { # method, field, warped, seconds
        local json
        json=$($bin eval --field "$2" --truth "$truth" ${mask:+--mask "$mask"} \
            --warped "$3" --target "$target" --json)
        python3 - "$json" "$name" "$1" "$4" >> "$out/table.md" <<'PY'
import json, sys
v = json.loads(sys.argv[1])
print(f"| {sys.argv[2]} | {sys.argv[3]} | {float(sys.argv[4]):.1f} | {v['mean_mm']:.2f} | "
      f"{100 * v['within_2_voxels']:.1f}% | {100 * v['within_4_voxels']:.1f}% | {v['correlation']:.3f} |")
PY
    }
    for device in ${DEVICES:-cpu gpu}; do
        for run in "$@"; do
            local label=${run%%|*} flags=${run#*|}
            local to="$dir/posereg-$device-${label// /-}"
            t=$(seconds $bin register --quiet --device "$device" --source "$source" --source-labels "$labels" \
                --target "$target" -o "$to" $flags)
            score "posereg $label ($device$( [ $device = gpu ] && echo ', lavapipe'))" "$to/field.nii.gz" "$to/warped.nii.gz" "$t"
        done
    done
    mkdir -p "$dir/elastix"
    t=$(seconds elastix -f "$target" -m "$source" \
        -p scripts/elastix/affine.txt -p scripts/elastix/bspline.txt -out "$dir/elastix" -threads "$threads")
    transformix -def all -tp "$dir/elastix/TransformParameters.1.txt" -out "$dir/elastix" -threads "$threads" >/dev/null
    score "elastix affine + B-spline" "$dir/elastix/deformationField.nii" "$dir/elastix/result.1.nii" "$t"
}

# phantom_pair DIR NAME SIZE DEGREES RUNS...
phantom_pair() {
    local dir=$1 name=$2 size=$3 deg=$4
    shift 4
    $bin phantom --size "$size" -o "$dir/straight" --seed 1 >/dev/null
    $bin phantom --size "$size" --flexion "$deg" -o "$dir/bent" --seed 2 >/dev/null
    compare "$dir" "$name" "$dir/straight/image.nii.gz" "$dir/straight/labels.nii.gz" \
        "$dir/bent/image.nii.gz" "$dir/bent/truth_field.nii.gz" "$dir/bent/labels.nii.gz" "$@"
}

# knee_pair DIR NAME SHRINK(x,y,z) DEGREES RUNS...
knee_pair() {
    local dir=$1 name=$2 shrink=$3 deg=$4
    shift 4
    mkdir -p "$dir"
    python3 - ../shared/data/knee-dess "$dir" "$shrink" <<'PY'
import sys, SimpleITK as sitk
data, out, shrink = sys.argv[1:]
image = sitk.BinShrink(sitk.Cast(sitk.ReadImage(f"{data}/image.nii.gz"), sitk.sitkFloat32),
                       [int(f) for f in shrink.split(",")])
labels = sitk.Resample(sitk.ReadImage(f"{data}/labels.nii.gz"), image, sitk.Transform(),
                       sitk.sitkNearestNeighbor, 0, sitk.sitkUInt8)
sitk.WriteImage(image, f"{out}/straight.nii.gz")
sitk.WriteImage(labels, f"{out}/straight_labels.nii.gz")
PY
    $bin bend "$dir/straight.nii.gz" --labels "$dir/straight_labels.nii.gz" --degrees "$deg" -o "$dir/bent" >/dev/null
    compare "$dir" "$name" "$dir/straight.nii.gz" "$dir/straight_labels.nii.gz" \
        "$dir/bent/target.nii.gz" "$dir/bent/truth_field.nii.gz" "" "$@"
}

# independent_pair DIR NAME SPACING DEGREES SEED [make_pair.py options...]
independent_pair() {
    local dir=$1 name=$2 spacing=$3 deg=$4 seed=$5
    shift 5
    local pair="$dir/pair" data=../shared/data/knee-dess
    [ -f "$pair/truth.json" ] || python3 scripts/make_pair.py --image $data/image.nii.gz \
        --labels $data/labels.nii.gz --degrees "$deg" --spacing "$spacing" --seed "$seed" "$@" \
        ${MAKE_PAIR_OPTS:-} -o "$pair"
    [ -f "$out/independent.md" ] || python3 scripts/score_pair.py --header > "$out/independent.md"
    iscore() { # method, field, seconds, [bone transforms]
        python3 scripts/score_pair.py "$pair" "$2" ${4:+--bones "$4"} --row "$name" "$1" "$3" \
            >> "$out/independent.md"
    }
    for device in $([ "$skip_posereg" = 1 ] || echo ${DEVICES:-cpu gpu}); do
        local to="$dir/posereg-$device"
        t=$(seconds $bin register --quiet --device "$device" --source "$pair/source.nii.gz" \
            --source-labels "$pair/source_labels.nii.gz" --target "$pair/target.nii.gz" -o "$to")
        iscore "posereg ($device$( [ $device = gpu ] && echo ', lavapipe'))" "$to/field.nii.gz" "$t" "$to/transform.json"
    done
    mkdir -p "$dir/elastix"
    t=$(seconds elastix -f "$pair/target.nii.gz" -m "$pair/source.nii.gz" -p scripts/elastix/affine_mi.txt \
        -p scripts/elastix/bspline_mi.txt -out "$dir/elastix" -threads "$threads")
    transformix -def all -tp "$dir/elastix/TransformParameters.1.txt" -out "$dir/elastix" -threads "$threads" >/dev/null
    iscore "elastix affine + B-spline (MI)" "$dir/elastix/deformationField.nii" "$t"
    t=$(seconds python3 scripts/demons.py "$pair/target.nii.gz" "$pair/source.nii.gz" "$dir/demons")
    iscore "SimpleITK affine + diffeomorphic demons" "$dir/demons/field.nii.gz" "$t"
    t=$(seconds env THREADS="$threads" python3 scripts/greedy.py "$pair/target.nii.gz" "$pair/source.nii.gz" "$dir/greedy")
    iscore "greedy affine + deformable (NCC)" "$dir/greedy/field.nii.gz" "$t"
}

for pair in ${PAIRS:-phantom10 phantom60 knee10}; do
    dir="$out/$pair"
    case $pair in
    phantom10 | phantom60)
        deg=${pair#phantom}
        phantom_pair "$dir" "half phantom $deg°" half "$deg" "with init|" ;;
    knee10)
        knee_pair "$dir" "real knee 10°" 2,2,1 10 "no init|--no-init" "with init|" ;;
    paper-phantom10)
        phantom_pair "$dir" "quarter phantom 10° (paper's scale)" quarter 10 "no init|--no-init" ;;
    paper-knee10)
        knee_pair "$dir" "real knee 10°, 64×64×40 (paper's scale)" 8,8,2 10 "no init|--no-init" ;;
    indep2-20 | indep2-45 | indep2-90 | indep1-20 | indep1-45 | indep1-90)
        mm=${pair:5:1} deg=${pair#*-}
        seed=$(( 10 + (mm == 2 ? 0 : 3) + (deg == 20 ? 1 : deg == 45 ? 2 : 3) ))
        independent_pair "$dir" "knee ${mm} mm, $deg°" "$mm" "$deg" "$seed" ;;
    indep2-20v | indep2-45v | indep2-90v | indep1-20v | indep1-45v | indep1-90v)
        mm=${pair:5:1} deg=${pair#*-} deg=${deg%v}
        seed=$(( 10 + (mm == 2 ? 0 : 3) + (deg == 20 ? 1 : deg == 45 ? 2 : 3) ))
        independent_pair "$dir" "knee ${mm} mm, $deg°, volume kept" "$mm" "$deg" "$seed" \
            --tissue incompressible ;;
    indep2-20f | indep2-45f | indep2-90f | indep1-20f | indep1-45f | indep1-90f)
        mm=${pair:5:1} deg=${pair#*-} deg=${deg%f}
        seed=$(( 10 + (mm == 2 ? 0 : 3) + (deg == 20 ? 1 : deg == 45 ? 2 : 3) ))
        independent_pair "$dir" "knee ${mm} mm, $deg°, volume kept, air free" "$mm" "$deg" "$seed" \
            --tissue incompressible --air free ;;
    indep2-fibula)
        independent_pair "$dir" "knee 2 mm, 20°, target cut (fibula 8% seen)" 2 20 7 --target-keep 1 0 0.75 ;;
    *)
        echo "unknown pair $pair" >&2
        exit 2 ;;
    esac
done
[ "$skip_posereg" = 1 ] || cat "$out/table.md"
[ -f "$out/independent.md" ] && cat "$out/independent.md"
