#!/usr/bin/env bash
# The thesis' shape ConvNet (width 128, 320 x 320 views, ch. 5) trained on a lent GPU, and K-fold
# validation of a shape recipe there (issue 31).
#
# Never needed: the shipped weights come from CPU runs (docs/training.md), and no test needs a
# GPU. The device machine has Python 3.12 with torch but none of this project, and a call carries
# at most 64 MiB, so the inputs are computed there from the 1024-point clouds:
#
#   here:    tools/train_shapes_gpu.sh prepare
#              .gpu/ (git-ignored): a cp312 wheel of rgbd_rs, trimesh's wheel (not on the device)
#              and the ModelNet10 point pack, about 33 MB
#   device:  run(command="bash tools/train_shapes_gpu.sh run", carry=[".gpu"], timeout_s=600)
#              installs the wheels, builds the cache on the machine's cores, trains on the GPU
#              until BUDGET_S, and brings back best.pt and last.pt as inference-only float16
#              copies (a file comes back only under 16 MiB; last.pt holds the per-epoch learning
#              curve), curve.png and the log under $OUT
#   device:  run(command="bash tools/train_shapes_gpu.sh cv", carry=[".gpu"], timeout_s=600)
#              K-fold validation of a recipe (default: the shipped CPU one, 32 px, width 32, 6
#              epochs, 8 scaled copies; RES_CV, WIDTH_CV, EPOCHS_CV, COPIES_CV and TRAIN_ARGS,
#              extra `rgbd train shapes` flags, change it): FOLDS (5) x SEEDS ("1 2") runs, each
#              trained without its fold, PARALLEL (10) at a time, read on their fold; the log
#              gives the accuracy over all 3991 training shapes of the first seed alone and of
#              the seeds averaged (each also weighted to TEST_COUNTS, ModelNet10's test-split
#              class counts from the thesis' Table 5.4), and cv.tgz the per-fold probabilities.
#              SCALE_RANGE_CV="LOW HIGH" draws the copies' factors from another range;
#              TEST_COUNTS="" leaves the weighting out. When the held-out 10 % saturates (issue
#              31: 96.2-97.5 % whatever is tried), this tells recipes apart on ten times as many
#              shapes. Not yet run on a device.
#   here:    tools/train_shapes_gpu.sh cv-here DIR
#              the same K-fold loop with this machine's Python into DIR (hours on 2 CPU cores)
#   here:    tools/train_shapes_gpu.sh smoke [cv]
#              the same steps at toy size on this CPU (a 40-shape pack, 32 px, width 8; cv: 2
#              folds of its 20 training shapes)
#
# Run once on the lent H200 (2026-12-04, docs/experiments.md): the cache took 133 s (27 ms a
# shape on 16 cores, 17 GB) and an epoch 23 s (8 loader workers), so 16 epochs fit the budget.
#
# Knobs (environment): RES (320), WIDTH (128), EPOCHS (16), COPIES (0: scaled copies per
# training shape), BATCH (32), LR (0.02), SEED (1), WORKERS (data loaders, <= 8), BUDGET_S
# (540: seconds from the script's start, install and cache included, to the end of training;
# keep it ~60 s under the call's timeout_s, less where the device has less time left).
# The recipe is the shipped CPU one (cosine, batch norm, dropout 0.5, label smoothing 0.1).
set -euo pipefail

here=$(cd "$(dirname "$0")/.." && pwd)
gpu="$here/.gpu"
RES=${RES:-320}
WIDTH=${WIDTH:-128}
EPOCHS=${EPOCHS:-16}
COPIES=${COPIES:-0}
BATCH=${BATCH:-32}
LR=${LR:-0.02}
SEED=${SEED:-1}
BUDGET_S=${BUDGET_S:-540}
WORKERS=${WORKERS:-$(($(nproc) < 8 ? $(nproc) : 8))}
FOLDS=${FOLDS:-5}
SEEDS=${SEEDS:-1 2}
SPLIT_SEED=${SPLIT_SEED:-1}
PARALLEL=${PARALLEL:-10}
TRAIN_ARGS=${TRAIN_ARGS:-}
TEST_COUNTS=${TEST_COUNTS-50,100,100,86,86,100,86,100,100,100}
SCALE_RANGE_CV=${SCALE_RANGE_CV:-}

prepare() {
    local data="${RGBD_DATA:-$here/../shared/data}/modelnet/modelnet10_1024.npz"
    [[ -f "$data" ]] || { echo "train_shapes_gpu: no ModelNet10 pack at $data (set RGBD_DATA)" >&2; exit 2; }
    local exclude
    exclude=$(git -C "$here" rev-parse --git-path info/exclude)
    [[ "$exclude" = /* ]] || exclude="$here/$exclude"
    grep -qx '/.gpu/' "$exclude" 2>/dev/null || echo '/.gpu/' >>"$exclude"
    rm -rf "$gpu" && mkdir -p "$gpu"
    # The device's Python is 3.12; maturin builds for it from its own sysconfig table when no
    # python3.12 is installed here.
    # The Makefile's target folder: only the binding crate is rebuilt for another Python.
    (cd "$here" && CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/rgbd_rs/target} \
        maturin build --release -q -i python3.12 -o "$gpu")
    "${PYTHON:-python3}" -m pip download -q --no-deps --only-binary=:all: -d "$gpu" "trimesh==$(pip_version trimesh)"
    cp "$data" "$gpu/"
    du -sh "$gpu"
    echo "now: run(command=\"bash tools/train_shapes_gpu.sh run\", carry=[\".gpu\"], timeout_s=600)"
}

pip_version() {
    "${PYTHON:-python3}" -c "import importlib.metadata as m; print(m.version('$1'))"
}

# train PY PACK WORK OUT: the cache, training until the budget (BUDGET_S from the script's
# start), then the files to bring back.
train() {
    local py=$1 pack=$2 work=$3 out=$4
    mkdir -p "$work" "$out"
    "$py" -m rgbd_rs.cli shapes cache --data "$pack" --out "$work/cache" --resolution "$RES" \
        --representations depth,volume,curvature --scale-copies "$COPIES" --quiet \
        2>&1 | tee -a "$out/log.txt"
    local left=$((BUDGET_S - SECONDS))
    du -sh "$work/cache" | tee -a "$out/log.txt"
    echo "cache done at $SECONDS s; training for at most $left s" | tee -a "$out/log.txt"
    ((left > 30)) || { echo "train_shapes_gpu: no time left to train" >&2; exit 3; }
    local rc=0
    timeout --signal=INT --kill-after=30 "$left" "$py" -m rgbd_rs.cli train shapes --cache "$work/cache" \
        --out "$work/run" --width "$WIDTH" --epochs "$EPOCHS" --batch-size "$BATCH" \
        --schedule cosine --lr "$LR" --batch-norm --dropout 0.5 --label-smoothing 0.1 \
        --seed "$SEED" --workers "$WORKERS" 2>&1 | tee -a "$out/log.txt" || rc=$?
    local how="finished"
    ((rc == 0)) || how="stopped (exit $rc; 124: the budget)"
    echo "training $how at $SECONDS s" | tee -a "$out/log.txt"
    local f
    for f in best last; do
        [[ -f "$work/run/$f.pt" ]] || continue
        "$py" -c "import sys; from rgbd_rs.shapes.train import ship; ship(sys.argv[1], sys.argv[2])" \
            "$work/run/$f.pt" "$out/$f.pt"
    done
    if [[ -f "$out/last.pt" ]]; then
        "$py" "$here/tools/plot_learning_curve.py" --checkpoint "$out/last.pt" \
            --out "$out/curve.png" --title "ModelNet10, ${RES} px, width ${WIDTH}" || true
    fi
    ls -la "$out"
    # Stopped at the budget is a result; any other failure is not.
    ((rc == 0 || rc == 124)) || exit "$rc"
    [[ -f "$out/best.pt" ]] || { echo "train_shapes_gpu: no completed epoch" >&2; exit 3; }
}

# cv_loop PY PACK WORK OUT: K-fold validation of the recipe (the environment's knobs) on the
# pack's training shapes: one cache, the fold name files, FOLDS x SEEDS runs that never see
# their fold (PARALLEL at a time), each fold's networks averaged on it, then every fold
# combined: what the held-out 10 % can no longer tell apart (validation shapes saturated).
cv_loop() {
    local py=$1 pack=$2 work=$3 out=$4
    local tool="$here/tools/eval_shapes_val.py"
    mkdir -p "$work" "$out"
    local -a range=()
    # shellcheck disable=SC2206 # two numbers, LOW HIGH
    [[ -n "$SCALE_RANGE_CV" ]] && range=(--scale-range $SCALE_RANGE_CV)
    "$py" -m rgbd_rs.cli shapes cache --data "$pack" --out "$work/cache" --resolution "$RES" \
        --representations depth,volume,curvature --scale-copies "$COPIES" ${range[@]+"${range[@]}"} --quiet \
        2>&1 | tee -a "$out/log.txt"
    echo "cache done at $SECONDS s" | tee -a "$out/log.txt"
    local i s
    local -a jobs=()
    for ((i = 0; i < FOLDS; i++)); do
        "$py" "$tool" --cache "$work/cache" --seed "$SPLIT_SEED" --folds "$FOLDS" --fold "$i" \
            --write-names "$work/fold$i.txt" >/dev/null
        for s in $SEEDS; do jobs+=("$i $s"); done
    done
    local job n=0
    local -a pids=() names=() logs=()
    for job in "${jobs[@]}"; do
        read -r i s <<<"$job"
        # shellcheck disable=SC2086 # TRAIN_ARGS is a list of flags
        "$py" -m rgbd_rs.cli train shapes --cache "$work/cache" --out "$work/f${i}_s$s" \
            --width "$WIDTH" --epochs "$EPOCHS" --batch-size "$BATCH" --schedule cosine \
            --lr "$LR" --batch-norm --dropout 0.5 --label-smoothing 0.1 --seed "$s" \
            --val-fraction 0 --exclude-names "$work/fold$i.txt" --workers "$WORKERS" --quiet \
            $TRAIN_ARGS >"$work/f${i}_s$s.log" 2>&1 &
        pids+=("$!")
        names+=("fold $i seed $s")
        logs+=("$work/f${i}_s$s.log")
        n=$((n + 1))
        if ((n % PARALLEL == 0)) || ((n == ${#jobs[@]})); then
            # Each run's own exit status: a run that failed or was killed part-way leaves a
            # last.pt of an earlier epoch, which must not be read as a finished network.
            local k rc
            for k in "${!pids[@]}"; do
                rc=0
                wait "${pids[$k]}" || rc=$?
                if ((rc != 0)); then
                    tail -5 "${logs[$k]}" >&2 || true
                    echo "train_shapes_gpu: ${names[$k]} failed (status $rc)" >&2
                    exit 3
                fi
            done
            pids=()
            names=()
            logs=()
        fi
    done
    echo "training done at $SECONDS s" | tee -a "$out/log.txt"
    local -a saved=() first=()
    for ((i = 0; i < FOLDS; i++)); do
        local -a ckpts=()
        for s in $SEEDS; do
            [[ -f "$work/f${i}_s$s/last.pt" ]] || {
                tail -5 "$work/f${i}_s$s.log" >&2
                echo "train_shapes_gpu: fold $i seed $s did not finish" >&2
                exit 3
            }
            ckpts+=("$work/f${i}_s$s/last.pt")
        done
        "$py" "$tool" --cache "$work/cache" --seed "$SPLIT_SEED" --folds "$FOLDS" --fold "$i" \
            --checkpoint "${ckpts[@]}" --save "$work/cv$i.npz" | tee -a "$out/log.txt"
        "$py" "$tool" --cache "$work/cache" --seed "$SPLIT_SEED" --folds "$FOLDS" --fold "$i" \
            --checkpoint "${ckpts[0]}" --save "$work/cv${i}_first.npz" >/dev/null
        saved+=("$work/cv$i.npz")
        first+=("$work/cv${i}_first.npz")
    done
    # The per-fold probabilities first: a bad TEST_COUNTS must not lose them.
    tar -czf "$out/cv.tgz" -C "$work" $(cd "$work" && ls cv*.npz fold*.txt)
    local -a counts=()
    [[ -n "$TEST_COUNTS" ]] && counts=(--class-counts "$TEST_COUNTS")
    echo "== the first seed alone" | tee -a "$out/log.txt"
    "$py" "$tool" --combine "${first[@]}" ${counts[@]+"${counts[@]}"} | tail -2 |
        tee -a "$out/log.txt"
    echo "== the seeds ($SEEDS) averaged" | tee -a "$out/log.txt"
    "$py" "$tool" --combine "${saved[@]}" ${counts[@]+"${counts[@]}"} | tail -2 |
        tee -a "$out/log.txt"
    echo "cross-validation done at $SECONDS s" | tee -a "$out/log.txt"
}

# The device's setup: this package's and trimesh's wheels, the data-loader check.
device_setup() {
    : "${OUT:?run on the device machine, where OUT is set}"
    local pack="$gpu/modelnet10_1024.npz"
    [[ -f "$pack" ]] || { echo "train_shapes_gpu: no $pack: run prepare here and carry .gpu" >&2; exit 2; }
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site "$gpu"/*.whl
    export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1
    nvidia-smi --query-gpu=name,memory.total --format=csv,noheader || true
    # Data-loader workers hand batches over in /dev/shm: BATCH shapes of 18 float32 maps of
    # RES x RES (6 depth views, 6 two-channel curvature views; the volumes are small), two
    # batches in flight per worker, twice that for headroom (240 MB a batch at the defaults).
    # Where it is smaller, load in the main process instead.
    local shm_mb batch_mb
    shm_mb=$(df -Pm /dev/shm 2>/dev/null | awk 'NR == 2 {print $4}')
    batch_mb=$((BATCH * 18 * RES * RES * 4 / 1000000 + 1))
    echo "cores $(nproc), /dev/shm free ${shm_mb:-?} MB, workers $WORKERS, ${batch_mb} MB a batch"
    if ((WORKERS > 0)) && ((${shm_mb:-0} < 4 * WORKERS * batch_mb)); then
        WORKERS=0
        echo "train_shapes_gpu: /dev/shm too small for data-loader workers: loading in the main process"
    fi
}

run() {
    device_setup
    train python3 "$gpu/modelnet10_1024.npz" /tmp/shapes_gpu "$OUT"
}

cv() {
    # The shipped CPU recipe unless told otherwise; the loader workers shared by the runs.
    RES=${RES_CV:-32} WIDTH=${WIDTH_CV:-32} EPOCHS=${EPOCHS_CV:-6} COPIES=${COPIES_CV:-8}
    WORKERS=$(($(nproc) / PARALLEL > 0 ? $(nproc) / PARALLEL : 1))
    device_setup
    cv_loop python3 "$gpu/modelnet10_1024.npz" /tmp/shapes_cv "$OUT"
}

cv_here() {
    local dir=${1:?cv-here DIR}
    local data="${RGBD_DATA:-$here/../shared/data}/modelnet/modelnet10_1024.npz"
    RES=${RES_CV:-32} WIDTH=${WIDTH_CV:-32} EPOCHS=${EPOCHS_CV:-6} COPIES=${COPIES_CV:-8}
    WORKERS=${WORKERS_CV:-0} PARALLEL=${PARALLEL_CV:-1}
    cv_loop "${PYTHON:-python3}" "$data" "$dir" "$dir/out"
}

smoke() {
    local work
    work=$(mktemp -d)
    "${PYTHON:-python3}" - "${RGBD_DATA:-$here/../shared/data}" "$work/pack.npz" <<'EOF'
import os, sys
import numpy as np
d = np.load(os.path.join(sys.argv[1], "modelnet/modelnet10_1024.npz"))
keep = np.concatenate([np.flatnonzero((d["label"] == c) & (d["split"] == s))[:2]
                       for c in range(len(d["classes"])) for s in (0, 1)])
np.savez(sys.argv[2], **{k: d[k][keep] if d[k].shape[:1] == d["label"].shape else d[k] for k in d.files})
EOF
    if [[ ${1:-} == cv ]]; then
        RES=32 WIDTH=8 EPOCHS=1 BATCH=8 WORKERS=0 COPIES=1 FOLDS=2 SEEDS="1 2" PARALLEL=2 \
            cv_loop "${PYTHON:-python3}" "$work/pack.npz" "$work" "$work/out"
        [[ -f "$work/out/cv.tgz" ]] || { echo "smoke cv: no cv.tgz" >&2; exit 1; }
    else
        RES=32 WIDTH=8 EPOCHS=${EPOCHS_SMOKE:-1} BATCH=8 WORKERS=0 train "${PYTHON:-python3}" "$work/pack.npz" "$work" "$work/out"
        [[ -f "$work/out/best.pt" ]] || { echo "smoke: no best.pt" >&2; exit 1; }
    fi
    echo "smoke: ok ($work/out)"
}

case "${1:-}" in
prepare | run | cv) "$1" ;;
smoke) smoke "${2:-}" ;;
cv-here) cv_here "${2:-}" ;;
*)
    sed -n '2,/^set -euo/p' "$0" | grep '^#' | sed 's/^# \{0,1\}//'
    exit 2
    ;;
esac
