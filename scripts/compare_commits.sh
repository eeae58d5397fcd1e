#!/usr/bin/env bash
# Proof that a change of the source tree changes no output byte: builds the commit BASE and the
# working tree NEW_TREE, runs both binaries on the same inputs and options, and compares every
# file they write with `cmp`. Meant for refactors, which must leave every output identical.
#
# usage: bash scripts/compare_commits.sh BASE [NEW_TREE]
#
#   BASE      a commit, branch or tag of this repository (e.g. HEAD, main~3). It is checked out
#             with `git worktree add --detach` in a temporary directory (removed at exit) and
#             built there with CARGO_TARGET_DIR=$BASE_TARGET_DIR.
#   NEW_TREE  the source tree to check (default: the repository this script lives in), built as
#             it is on disk, uncommitted changes included, with `cargo build --release --locked`
#             in $NEW_TARGET_DIR.
#
# Environment:
#   BASE_TARGET_DIR   cargo target dir of BASE (default: target-cmp-base beside the repository,
#                     kept between runs so that the dependencies are not rebuilt; delete it when
#                     done)
#   NEW_TARGET_DIR    cargo target dir of NEW_TREE (default: NEW_TREE/target, its normal one)
#   DATA_DIR          the shared inputs (default: ../shared/data beside the repository). Read
#                     only: nothing is copied into the repository
#   TMPDIR            where the outputs go (a temporary directory, removed at exit)
#
# Output: one line per case, `same` or `DIFFERENT` (with the file and its first differing byte,
# or the exit codes), then the elapsed time and a final line `N same, M different`. A case whose
# run fails in both builds with the same exit code counts as same (and says so). Exit status 0
# when every case is the same, 1 when any differs or a run fails in one build only, 2 when a
# build or the setup fails.
#
# The cases (3 to 5 minutes of runs on 2 cores, plus the two builds, 1 to 2 minutes each):
#   las        every file of DATA_DIR/las with default options (.las -> .las, .laz -> .laz), and
#              one .las written as .laz and as .ply
#   objects    every file of DATA_DIR/objects (.ply .pcd .obj .xyz) -> .ply with default options,
#              one -> .ascii.ply, --orient outward --ignore-file-normals, --sample-faces 20k
#   estimator  each --estimator on las/Haystack_Rock.las, vcm --features, --directions --f64
#   propagate  --orient propagate on the bunny (one tile and 13 tiles) and on a 36-tile LAS file
#   scene      bcts_1.laz bcts_2.laz -o DIR/ (one scene, one output per input)
#   memory     --memory 64M with small tiles (in-memory buckets), with a tile larger than the
#              part budget (quadtree parts), and on 2M generated points (buckets spilled)
#   generate   generate terrain to .las and .laz
#   errors     a usage error and an unsupported input: the same exit code in both
#   resume     NEW killed (kill -9; SIGINT, exit 130) after a few finished tiles, then the same
#              command rerun to completion, against BASE's uninterrupted run
set -euo pipefail

usage() {
    sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//' >&2
    exit 2
}
[ $# -ge 1 ] && [ $# -le 2 ] || usage
case $1 in -h | --help) usage ;; esac

START=$SECONDS
REPO=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BASE=$1
NEW_TREE=$(cd "${2:-$REPO}" && pwd)
DATA=$(cd "${DATA_DIR:-$REPO/../shared/data}" && pwd)
BASE_TARGET_DIR=${BASE_TARGET_DIR:-$(dirname "$REPO")/target-cmp-base}
NEW_TARGET_DIR=${NEW_TARGET_DIR:-$NEW_TREE/target}
LAS=$DATA/las
OBJ=$DATA/objects
[ -d "$LAS" ] && [ -d "$OBJ" ] || { echo "compare_commits: no inputs in $DATA (set DATA_DIR)" >&2; exit 2; }
BASE_COMMIT=$(git -C "$REPO" rev-parse --verify --quiet "$BASE^{commit}") \
    || { echo "compare_commits: $BASE is not a commit of $REPO" >&2; exit 2; }

TMP=$(mktemp -d "${TMPDIR:-/tmp}/tilecurv-compare.XXXXXX")
BASE_TREE=$TMP/base-tree # the BASE worktree
BG_PID=""                # a run of the resume cases, while it is in the background
cleanup() {
    if [ -n "$BG_PID" ]; then kill -9 "$BG_PID" 2>/dev/null || true; fi
    if [ -d "$BASE_TREE" ]; then git -C "$REPO" worktree remove --force "$BASE_TREE" 2>/dev/null || true; fi
    rm -rf "$TMP"
    git -C "$REPO" worktree prune 2>/dev/null || true
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# ---------------------------------------------------------------------------------------------
# Builds

# build LABEL TREE TARGET_DIR: cargo build --release --locked; copies the binary to $TMP/bin so
# that a rebuild of the tree while the cases run cannot change it.
build() {
    local label=$1 tree=$2 target=$3 t0=$SECONDS
    echo "building $label: $tree (CARGO_TARGET_DIR=$target)"
    if ! (cd "$tree" && CARGO_TARGET_DIR=$target cargo build --release --locked) >"$TMP/build-$label.log" 2>&1; then
        echo "compare_commits: the build of $label failed:" >&2
        tail -n 40 "$TMP/build-$label.log" >&2
        exit 2
    fi
    mkdir -p "$TMP/bin"
    cp "$target/release/tilecurv" "$TMP/bin/$label"
    echo "  built in $((SECONDS - t0)) s: $("$TMP/bin/$label" --version)"
}

git -C "$REPO" worktree add --quiet --detach "$BASE_TREE" "$BASE_COMMIT"
NEW_DESC=$(git -C "$NEW_TREE" rev-parse --short HEAD 2>/dev/null || echo "not a git tree")
if [ -n "$(git -C "$NEW_TREE" status --porcelain 2>/dev/null)" ]; then NEW_DESC="$NEW_DESC + uncommitted changes"; fi
echo "BASE = $BASE ($(git -C "$REPO" log -1 --format='%h %s' "$BASE_COMMIT" | cut -c1-80))"
echo "NEW  = $NEW_TREE ($NEW_DESC)"
echo "data = $DATA; outputs in $TMP"
build base "$BASE_TREE" "$BASE_TARGET_DIR"
build new "$NEW_TREE" "$NEW_TARGET_DIR"
BASE_BIN=$TMP/bin/base
NEW_BIN=$TMP/bin/new
BUILD_TIME=$((SECONDS - START))

# ---------------------------------------------------------------------------------------------
# Running and comparing

N_SAME=0
N_DIFF=0
N_BOTH_FAILED=0
CASE_NO=0
RC=0 # exit code of the last run_one

# run_one BIN DIR ARG...: runs BIN with the arguments, `%OUT%` in them replaced by DIR (created
# empty); stdout and stderr go to DIR.log. Sets RC.
run_one() {
    local bin=$1 dir=$2 a
    shift 2
    local args=()
    for a in "$@"; do args+=("${a//%OUT%/$dir}"); done
    rm -rf "$dir"
    mkdir -p "$dir"
    RC=0
    "$bin" "${args[@]}" >"$dir.log" 2>&1 </dev/null || RC=$?
}

# compare_dirs A B: every file under A and B (hidden ones included: a leftover work directory
# counts) must exist in both and be byte-identical. Sets WHY on a difference.
WHY=""
compare_dirs() {
    local a=$1 b=$2 la lb f msg byte
    la=$(cd "$a" && find . -type f | sed 's|^\./||' | sort)
    lb=$(cd "$b" && find . -type f | sed 's|^\./||' | sort)
    if [ "$la" != "$lb" ]; then
        WHY="not the same files: base [$(echo $la)], new [$(echo $lb)]"
        return 1
    fi
    while IFS= read -r f; do
        [ -n "$f" ] || continue
        if ! msg=$(cmp -- "$a/$f" "$b/$f" 2>&1); then
            byte=$(sed -n 's/.* differ: \(byte\|char\) \([0-9]*\).*/\2/p' <<<"$msg")
            if [ -n "$byte" ]; then
                WHY="$f: first difference at byte $byte"
            else # one is a prefix of the other: cmp says EOF on the shorter one
                WHY="$f: ${msg//$a/base}"
                WHY=${WHY//$b/new}
            fi
            WHY="$WHY (sizes $(stat -c %s "$a/$f") / $(stat -c %s "$b/$f") bytes)"
            return 1
        fi
    done <<<"$la"
}

# report NAME VERDICT DETAIL [LOG...]: prints the case's line and counts it; the tails of the
# given logs (those of failed runs) are shown under a DIFFERENT line.
report() {
    local name=$1 verdict=$2 detail=$3 log
    shift 3
    if [ "$verdict" = same ]; then
        N_SAME=$((N_SAME + 1))
        printf '%-9s  %s%s\n' same "$name" "${detail:+  ($detail)}"
    else
        N_DIFF=$((N_DIFF + 1))
        printf '%-9s  %s: %s\n' DIFFERENT "$name" "$detail"
        for log in "$@"; do
            [ -s "$log" ] || continue
            echo "    ${log#"$TMP"/}:"
            tail -n 5 "$log" | sed 's/^/      /'
        done
    fi
}

# judge NAME BASE_RC NEW_RC BASE_DIR NEW_DIR [NOTE]: the verdict of a case from both runs.
judge() {
    local name=$1 brc=$2 nrc=$3 bdir=$4 ndir=$5 note=${6:-}
    if [ "$brc" != "$nrc" ]; then
        report "$name" DIFFERENT "exit code base $brc, new $nrc" "$bdir.log" "$ndir.log"
    elif ! compare_dirs "$bdir" "$ndir"; then
        report "$name" DIFFERENT "$WHY"
    elif [ "$brc" != 0 ]; then
        N_BOTH_FAILED=$((N_BOTH_FAILED + 1))
        report "$name" same "both failed with exit $brc${note:+; $note}"
    elif [ -z "$(cd "$ndir" && find . -type f)" ]; then
        report "$name" DIFFERENT "exit 0 but no output file in either" "$bdir.log" "$ndir.log"
    else
        report "$name" same "$note"
    fi
}

# compare NAME ARG...: runs BASE and NEW with the same arguments (`%OUT%` is each one's output
# directory) and compares everything they write. With EXPECT_LOG=TEXT in its environment, a
# NEW log without TEXT is noted (it checks that the case exercises what it claims).
compare() {
    local name=$1
    shift
    CASE_NO=$((CASE_NO + 1))
    local b=$TMP/base/$CASE_NO n=$TMP/new/$CASE_NO
    run_one "$BASE_BIN" "$b" "$@"
    local brc=$RC
    run_one "$NEW_BIN" "$n" "$@"
    local note=""
    if [ "$RC" = 0 ] && [ -n "${EXPECT_LOG:-}" ] && ! grep -q "$EXPECT_LOG" "$n.log"; then
        note="warning: the new run's log does not say \"$EXPECT_LOG\""
    fi
    judge "$name" "$brc" "$RC" "$b" "$n" "$note"
    rm -rf "$b" "$n"
}

# ---------------------------------------------------------------------------------------------
# Cases

# 1. Every LAS/LAZ file, default options, output in the input's format; a .las to .laz and .ply.
case_las() {
    local f n
    for f in "$LAS"/*.las "$LAS"/*.laz; do
        n=$(basename "$f")
        compare "las: $n" process "$f" -o "%OUT%/$n"
    done
    compare "las: Haystack_Rock.las -> .laz" process "$LAS/Haystack_Rock.las" -o %OUT%/Haystack_Rock.laz
    compare "las: Haystack_Rock.las -> .ply" process "$LAS/Haystack_Rock.las" -o %OUT%/Haystack_Rock.ply
}

# 2. Every object (PLY, PCD, OBJ, XYZ) to PLY with default options (all of them run with the
# default --orient up; their own normals are used where they have some), plus ASCII PLY,
# outward PCA normals and sampled mesh faces.
case_objects() {
    local f n
    for f in "$OBJ"/*; do
        n=$(basename "$f")
        compare "objects: $n" process "$f" -o "%OUT%/${n%.*}.ply"
    done
    compare "objects: kitten.xyz -> .ascii.ply" process "$OBJ/kitten.xyz" -o %OUT%/kitten.ascii.ply
    compare "objects: sphere_20k_normal.xyz --orient outward --ignore-file-normals" \
        process "$OBJ/sphere_20k_normal.xyz" --orient outward --ignore-file-normals -o %OUT%/sphere.ply
    compare "objects: fandisk.obj --sample-faces 20k" process "$OBJ/fandisk.obj" --sample-faces 20k -o %OUT%/fandisk.ply
}

# 3. Every estimator, the VCM features, directions in f64 (vcm takes about 20 s per run).
case_estimators() {
    local e in=$LAS/Haystack_Rock.las
    for e in cnc-avg-hexagram cnc-hexagram cnc-uniform cnc-delaunay apss aso wme jet vcm; do
        compare "estimator: $e" process "$in" --estimator "$e" -o %OUT%/haystack.las
    done
    compare "estimator: vcm --features" process "$in" --estimator vcm --features -o %OUT%/haystack.las
    compare "estimator: --directions --f64" process "$in" --directions --f64 -o %OUT%/haystack.las
}

# 4. Normal propagation: the bunny in one tile and in 13 tiles (signs reconciled through the
# halos), and a LAS file of 36 tiles.
case_propagate() {
    compare "propagate: bun_zipper.ply" process "$OBJ/bun_zipper.ply" --orient propagate -o %OUT%/bunny.ply
    compare "propagate: bun_zipper.ply --tile 0.05 (13 tiles)" \
        process "$OBJ/bun_zipper.ply" --orient propagate --tile 0.05 -o %OUT%/bunny.ply
    compare "propagate: Topography.las (36 tiles)" process "$LAS/Topography.las" --orient propagate -o %OUT%/topo.las
}

# 5. Two adjacent files as one scene, one output each in a directory.
case_scene() {
    compare "scene: bcts_1.laz bcts_2.laz -o DIR/" process "$LAS/bcts_1.laz" "$LAS/bcts_2.laz" -o %OUT%/scene/
}

# 6. Small memory budgets. At 64M (the minimum) autzen's buckets stay in memory; a 500m tile
# holds 110k points, past the ~21k core points a part may have, so it is computed in quadtree
# parts; 2M points' buckets exceed 2/5 of the budget and spill to the work directory.
case_memory() {
    compare "memory: autzen_trim.las --memory 64M --tile 20m" \
        process "$LAS/autzen_trim.las" --memory 64M --tile 20m -o %OUT%/autzen.las
    compare "memory: autzen_trim.las --memory 64M --tile 500m (quadtree parts)" \
        process "$LAS/autzen_trim.las" --memory 64M --tile 500m -o %OUT%/autzen.las
    EXPECT_LOG="buckets spilled" compare "memory: terrain 2M --memory 64M --tile 20m (buckets spilled)" \
        process "$TERRAIN" --memory 64M --tile 20m -o %OUT%/terrain.las
}

# 7. The terrain generator, both formats.
case_generate() {
    compare "generate: terrain --points 300k --seed 3 -> .las" generate terrain --points 300k --seed 3 -o %OUT%/terrain.las
    compare "generate: terrain --points 300k --seed 3 -> .laz" generate terrain --points 300k --seed 3 -o %OUT%/terrain.laz
}

# Failure paths: the same exit code in both (these cases are expected to fail).
case_errors() {
    compare "errors: --features without --estimator vcm" process "$LAS/Haystack_Rock.las" --features -o %OUT%/x.las
    compare "errors: unsupported input format" process "$DATA/README.md" -o %OUT%/x.las
}

# 8. resume NAME SIGNAL EXPECTED_EXIT ARG...: NEW is started in the background, sent SIGNAL once
# its work directory holds RESUME_MIN_TILES finished tiles, must then exit with EXPECTED_EXIT
# and leave no output, and the same command run again must finish from the kept tiles. Its
# output is compared with BASE's uninterrupted run. The output must be %OUT%/terrain.las.
RESUME_MIN_TILES=${RESUME_MIN_TILES:-5}
resume() {
    local name=$1 sig=$2 want=$3
    shift 3
    CASE_NO=$((CASE_NO + 1))
    local b=$TMP/base/$CASE_NO n=$TMP/new/$CASE_NO
    run_one "$BASE_BIN" "$b" "$@"
    local brc=$RC

    local args=() a
    for a in "$@"; do args+=("${a//%OUT%/$n}"); done
    local out=$n/terrain.las results=$n/.terrain.las.tilecurv/results
    rm -rf "$n"
    mkdir -p "$n"
    "$NEW_BIN" "${args[@]}" >"$n.log1" 2>&1 </dev/null &
    BG_PID=$!
    local tiles=() waited=0
    shopt -s nullglob
    while kill -0 "$BG_PID" 2>/dev/null; do
        tiles=("$results"/tile_*.res)
        [ ${#tiles[@]} -lt "$RESUME_MIN_TILES" ] || break
        sleep 0.02
        waited=$((waited + 1))
        [ $waited -lt 6000 ] || break # 2 minutes
    done
    kill -s "$sig" "$BG_PID" 2>/dev/null || true
    local rc=0
    wait "$BG_PID" 2>/dev/null || rc=$? # 2>/dev/null: no "Killed" notice from bash
    BG_PID=""
    tiles=("$results"/tile_*.res)
    shopt -u nullglob
    local kept=${#tiles[@]}
    if [ "$rc" != "$want" ]; then
        report "$name" DIFFERENT "the interrupted run exited $rc, not $want (finished before the signal?)" "$n.log1"
    elif [ -e "$out" ]; then
        report "$name" DIFFERENT "the interrupted run left an output" "$n.log1"
    elif [ "$kept" -lt "$RESUME_MIN_TILES" ]; then
        report "$name" DIFFERENT "only $kept finished tiles were kept in the work directory" "$n.log1"
    else
        "$NEW_BIN" "${args[@]}" >"$n.log" 2>&1 </dev/null && RC=0 || RC=$?
        if [ "$RC" = 0 ] && ! grep -Eq 'already done|[1-9][0-9]* resumed' "$n.log"; then
            report "$name" DIFFERENT "the rerun did not resume from the $kept kept tiles" "$n.log"
        else
            judge "$name" "$brc" "$RC" "$b" "$n" "interrupted with $kept tiles done, exit $rc, resumed"
        fi
    fi
    rm -rf "$b" "$n"
}

case_resume() {
    # Default memory: buckets in memory, rescanned on the rerun.
    resume "resume: kill -9 then rerun (terrain 2M, --tile 20m --threads 1)" KILL 137 \
        process "$TERRAIN" --tile 20m --threads 1 -o %OUT%/terrain.las
    # Spilled buckets: the rerun reopens them from the work directory.
    resume "resume: SIGINT (exit 130) then rerun (terrain 2M, --tile 20m --threads 1 --memory 64M)" INT 130 \
        process "$TERRAIN" --tile 20m --threads 1 --memory 64M -o %OUT%/terrain.las
}

# The 2M-point input of the memory and resume cases (about 120 MB), generated by BASE.
mkdir -p "$TMP/input"
TERRAIN=$TMP/input/terrain_2M.las
"$BASE_BIN" generate terrain --points 2M --seed 3 --quiet -o "$TERRAIN"

echo
case_las
case_objects
case_estimators
case_propagate
case_scene
case_memory
case_generate
case_errors
case_resume

echo
[ "$N_BOTH_FAILED" = 0 ] || echo "$N_BOTH_FAILED of the same cases failed in both builds with the same exit code"
echo "elapsed: $((SECONDS - START)) s (builds $BUILD_TIME s, cases $((SECONDS - START - BUILD_TIME)) s)"
echo "$N_SAME same, $N_DIFF different"
[ "$N_DIFF" = 0 ]
