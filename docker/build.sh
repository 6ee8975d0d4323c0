#!/usr/bin/env bash
# Build the images: docker/build.sh [test] [runtime] [user-sut] [fiss-sut]   (default: all four)
#   localhost/evoscen-test     the test target (make test inside)
#   localhost/evoscen          the runtime target (run_scenario.py; graph_node.py for compose)
#   localhost/evoscen-user-sut a user's SUT built only from examples/ (docker/user-sut.Dockerfile)
#   localhost/evoscen-fiss     the runtime image + the fiss SUT plug-in (docker/fiss-sut.Dockerfile;
#                              build runtime first)
# BASE: $EVOSCEN_BASE, else localhost/debian:bookworm-slim when it exists (docker/offline-base.sh),
# else the Dockerfile's default (the official Debian image). This machine's pip settings go in as
# the build secret "pipconf" (docker/pipconf.py); nothing site-specific is stored in an image.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd); root=$(dirname "$here")
. "$here/engine.sh"
targets=("$@"); [ ${#targets[@]} -eq 0 ] && targets=(test runtime user-sut fiss-sut)
base=${EVOSCEN_BASE:-}
if [ -z "$base" ] && $ENGINE image exists localhost/debian:bookworm-slim 2>/dev/null; then base=localhost/debian:bookworm-slim; fi
if [ -z "$base" ] && [ "$ENGINE" = docker ] && docker image inspect localhost/debian:bookworm-slim >/dev/null 2>&1; then
  base=localhost/debian:bookworm-slim
fi
site=$here/.work/pipsite; rm -rf "$site"; mkdir -p "$site"
mapfile -t vols < <(python3 "$here/pipconf.py" "$site" --engine "$ENGINE")
args=(--secret "id=pipconf,src=$site/pip.conf" ${base:+--build-arg "BASE=$base"})
[ "$ENGINE" = podman ] && args+=(--network host "${vols[@]}")
[ "$ENGINE" = docker ] && export DOCKER_BUILDKIT=1
for t in "${targets[@]}"; do
  s=$(date +%s); log=$here/.work/build-$t.log
  case $t in
    test)     cmd=(--target test -t localhost/evoscen-test:latest -f "$here/Dockerfile" "$root") ;;
    runtime)  cmd=(--target runtime -t localhost/evoscen:latest -f "$here/Dockerfile" "$root") ;;
    user-sut) cmd=(-t localhost/evoscen-user-sut:latest -f "$here/user-sut.Dockerfile" "$root/examples") ;;
    fiss-sut) cmd=(-t localhost/evoscen-fiss:latest -f "$here/fiss-sut.Dockerfile" "$root") ;;
    *) echo "error: docker/build.sh: unknown target '$t' (expected test, runtime, user-sut or fiss-sut)" >&2; exit 2 ;;
  esac
  if ! $ENGINE build "${args[@]}" "${cmd[@]}" >"$log" 2>&1; then
    tail -n 30 "$log" >&2; echo "error: docker/build.sh: building $t failed (log: $log)" >&2; exit 1
  fi
  echo "built $t in $(( $(date +%s) - s )) s (log: $log)"
done
$ENGINE images --format '{{.Repository}}:{{.Tag}} {{.Size}}' | grep -E 'evoscen|debian' || true
