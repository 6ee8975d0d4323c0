#!/usr/bin/env bash
# Make podman usable on a host like this project's CI machines (Debian 12, root, no image registry,
# no systemd in the machine, hybrid cgroups, no CAP_SYS_RESOURCE) without editing /etc/containers:
#   1. apt: podman, runc, mmdebstrap        2. private podman configuration in docker/.work/conf
#   3. podman-compose (pinned) in docker/.work/venv
#   4. the base image localhost/debian:bookworm-slim from the Debian mirror (docker/offline-base.sh)
# Idempotent. Air-gapped users with a Debian mirror need steps 1-4 too; internet-connected docker
# users need none of it.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
W=$here/.work
mkdir -p "$W/conf"
if ! command -v podman >/dev/null || ! command -v runc >/dev/null || ! command -v mmdebstrap >/dev/null; then
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends podman runc mmdebstrap >/dev/null
fi
# runc, not crun: crun 1.8 refuses a hybrid cgroup v1 + v2 layout. ulimits: without
# CAP_SYS_RESOURCE podman's default nofile/nproc cannot be set, so use the current hard limits.
# events to a file: there is no journald/systemd.
NOFILE=$(ulimit -Hn); NPROC=$(ulimit -Hu)
if [ "$NPROC" = unlimited ] || [ "$NPROC" -gt 32768 ]; then NPROC=32768; fi
[ "$NOFILE" = unlimited ] && NOFILE=1048576
cat > "$W/conf/storage.conf" <<CONF
[storage]
driver = "overlay"
graphroot = "$W/storage"
runroot = "$W/runroot"
CONF
cat > "$W/conf/containers.conf" <<CONF
[containers]
default_ulimits = ["nofile=$NOFILE:$NOFILE", "nproc=$NPROC:$NPROC"]
[engine]
runtime = "runc"
cgroup_manager = "cgroupfs"
events_logger = "file"
tmp_dir = "$W/libpodtmp"
CONF
export CONTAINERS_CONF=$W/conf/containers.conf CONTAINERS_STORAGE_CONF=$W/conf/storage.conf
if [ ! -x "$W/venv/bin/podman-compose" ]; then
  python3 -m venv "$W/venv"
  "$W/venv/bin/pip" install --quiet --disable-pip-version-check podman-compose==1.6.0
fi
podman image exists localhost/debian:bookworm-slim || bash "$here/offline-base.sh"
echo "podman ready: $(podman --version), $("$W/venv/bin/podman-compose" --version 2>/dev/null | tail -1)"
