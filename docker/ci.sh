#!/usr/bin/env bash
# The container job of CI (.ci/run runs it after the native suite; .github/workflows/ci.yml too):
#   1. the engine: docker when its daemon answers, else podman (docker/setup-podman.sh: installs and
#      configures it and makes the base image from the Debian mirror: no image registry needed)
#   2. the images: test, runtime, user-sut, fiss-sut (the runtime image + the fiss plug-in)
#   3. end-to-end tests of the node graph inside the test image, no network: a lockstep graph (its bag and
#      live report), a killed controller and the wire (IMAGE_E2E below; the whole suite ran natively just before; killed nodes, an external SUT
#      and BV nodes in containers: stages 4-7);
#      the unit tests ran natively on the same requirements.txt (docs/docker.md)
#   4. a compose graph (one container per node, three BV containers: one per BV node of the default
#      partition) whose bag equals the in-process bag of the same configuration and seed, byte for
#      byte (in-process run in the runtime image)
#   5. one of the three BV containers killed mid-run: the graph ends with status 4 (a node died;
#      the deadline abort is its consequence) and a readable bag whose last fault is that BV node's abort
#   6. a user's SUT container built only from examples/ drives the SUT in a compose graph
#   7. the third-party planner FISS+ (the fiss plug-in) as the SUT node in its own container: the
#      bag equals the in-process bag of --sut fiss on the same seed and steps, byte for byte
# Needs the project's .venv on the host (make setup) for the bag checks (docker/check_bag.py).
#   docker/ci.sh              everything above
#   docker/ci.sh --build      steps 1-2 only (.ci/run runs them at low priority beside the native suite)
#   docker/ci.sh --no-build   steps 3-7 (the images are there)
set -euo pipefail
mode=${1:-all}
case $mode in all|--build|--no-build) ;; *) echo "error: docker/ci.sh: unknown option '$mode' (expected --build or --no-build)" >&2; exit 2 ;; esac
here=$(cd "$(dirname "$0")" && pwd); root=$(dirname "$here"); cd "$root"
T0=$(date +%s)
stage() { echo "=== container job: $* ($(( $(date +%s) - T0 )) s)"; }
if [ "$mode" != --no-build ]; then
  if ! { command -v docker >/dev/null && docker info >/dev/null 2>&1; }; then
    stage "podman set-up"; bash docker/setup-podman.sh
  fi
  . docker/engine.sh
  stage "images ($ENGINE)"
  bash docker/build.sh test runtime user-sut fiss-sut
  [ "$mode" = --build ] && { stage "images built"; exit 0; }
fi
. docker/engine.sh
# the bag checks import the workspace packages: through the colcon overlay (a symlink install's
# packages are not importable from a bare site-packages path)
check() { ( set +u; . "$root/.venv/bin/activate" && . "$root/ros2_ws/install/setup.sh" && python "$here/check_bag.py" "$@" ); }
out=$root/runs/ci-container; rm -rf "$out"; mkdir -p "$out"

# [choice] the node-graph end-to-end tests, not all 240: the native job has just run every test on the same
# requirements.txt; what the image changes is processes, DDS and the file system, which these exercise
# (docs/docker.md, "CI in containers"); `make docker-test` runs the whole suite in the image
# (the graph's bag against the in-process one is step 4's check in containers, messages on the wire the native
# job's tests/test_wire.py; docs/docker.md)
IMAGE_E2E="tests/test_graph.py::test_graph_run_completes tests/test_graph.py::test_killed_controller_aborts_cleanly"
stage "node-graph end-to-end tests in the test image"
$ENGINE run --rm --network none --shm-size=256m localhost/evoscen-test:latest make test PYTEST_ARGS="-q -p no:cacheprovider -m e2e $IMAGE_E2E"

stage "compose graph vs in-process bag"
bash docker/compose-run.sh --out "$out/graph" -- --steps 600 --seed 3 --no-plots
mkdir -p "$out/inprocess"; [ "$(id -u)" = 0 ] && chown 10001:10001 "$out/inprocess"
$ENGINE run --rm -v "$out/inprocess:/data" localhost/evoscen:latest --mode inprocess --steps 600 --seed 3 --no-plots \
  --quiet --out /data --overwrite >/dev/null
check equal "$out/graph/bag" "$out/inprocess/bag"

stage "BV container killed mid-run (bv-mutual of three)"
proj=evoscen-ci-kill-$$
bash docker/compose-run.sh --out "$out/kill" --project "$proj" -- --steps 20000 --seed 5 --deadline 0.5 --max-misses 3 \
  --no-plots &
run=$!
for _ in $(seq 1 240); do  # until the run is under way: the bag grows past its first chunk
  size=$(stat -c %s "$out/kill/bag/bag_0.mcap" 2>/dev/null || echo 0)
  [ "$size" -gt 200000 ] && break
  sleep 0.5
done
bv=$($ENGINE ps -q --filter "label=com.docker.compose.project=$proj" --filter "label=com.docker.compose.service=bv-mutual")
[ -n "$bv" ] || { echo "error: no running bv-mutual container to kill"; exit 1; }
$ENGINE kill "$bv" >/dev/null
rc=0; wait $run || rc=$?
echo "graph status after the BV kill: $rc (expected 4: a node died)"
[ "$rc" = 4 ] || exit 1
check aborted "$out/kill/bag" evoscen_bv_mutual

stage "a user's SUT container (examples/)"
bash docker/compose-run.sh --out "$out/user-sut" --user-sut -- --steps 300 --seed 1 --no-plots
check complete "$out/user-sut/bag" 300

stage "the fiss planner in its own SUT container vs in-process"
bash docker/compose-run.sh --out "$out/fiss" --fiss-sut -- --steps 300 --seed 3 --no-plots
mkdir -p "$out/fiss-inprocess"; [ "$(id -u)" = 0 ] && chown 10001:10001 "$out/fiss-inprocess"
$ENGINE run --rm -v "$out/fiss-inprocess:/data" localhost/evoscen-fiss:latest --mode inprocess --sut fiss --steps 300 \
  --seed 3 --no-plots --quiet --out /data --overwrite >/dev/null
check equal "$out/fiss/bag" "$out/fiss-inprocess/bag"
stage "done"
