#!/usr/bin/env bash
# The base image without an image registry: a minimal Debian bookworm made from the Debian mirror
# (mmdebstrap) and imported as localhost/debian:bookworm-slim. Build against it with
# --build-arg BASE=localhost/debian:bookworm-slim (docker/build.sh does when the image exists).
# Uses the host's apt sources (/etc/apt/sources.list.d/debian.sources when present) and accepts
# a dated mirror snapshot (Check-Valid-Until false, also kept in the image for apt-get in builds).
# Needs root and mmdebstrap; the engine from docker/engine.sh (docker or podman).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
. "$here/engine.sh"
IMAGE=${1:-localhost/debian:bookworm-slim}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
mirror=(); [ -f /etc/apt/sources.list.d/debian.sources ] && mirror=(/etc/apt/sources.list.d/debian.sources)
mmdebstrap --quiet --variant=minbase --mode=root \
  --aptopt='Acquire::Check-Valid-Until "false"' --aptopt='Acquire::Languages "none"' \
  --dpkgopt='path-exclude=/usr/share/man/*' --dpkgopt='path-exclude=/usr/share/doc/*' \
  --dpkgopt='path-include=/usr/share/doc/*/copyright' --dpkgopt='path-exclude=/usr/share/locale/*' \
  --dpkgopt='path-exclude=/usr/share/info/*' \
  --customize-hook='rm -rf "$1"/var/lib/apt/lists/* "$1"/var/cache/apt/*' \
  bookworm "$tmp/base.tar" "${mirror[@]}"
$ENGINE import --change 'CMD ["bash"]' "$tmp/base.tar" "$IMAGE" >/dev/null
echo "base image: $IMAGE ($(du -h "$tmp/base.tar" | cut -f1) tar)"
