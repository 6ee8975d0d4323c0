#!/usr/bin/env bash
# Sourced by the docker/ scripts and the Makefile's docker targets: picks the container engine.
#   ENGINE   docker (when its daemon answers) or podman, whichever is installed; EVOSCEN_ENGINE overrides
#   COMPOSE  "docker compose" for docker, podman-compose for podman
# podman on a host without registry/systemd (this project's CI machines) is configured privately
# by docker/setup-podman.sh; its settings, if present in docker/.work/conf, are picked up here.
_here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
if [ -n "${EVOSCEN_ENGINE:-}" ]; then
  ENGINE=$EVOSCEN_ENGINE
elif command -v docker >/dev/null 2>&1 && docker info >/dev/null 2>&1; then
  ENGINE=docker
elif command -v podman >/dev/null 2>&1; then
  ENGINE=podman
else
  echo "error: no container engine: install docker (with its daemon running) or podman (apt install podman runc; on a host without an image registry also see docker/setup-podman.sh)" >&2
  return 2 2>/dev/null || exit 2
fi
if [ "$ENGINE" = podman ] && [ -f "$_here/.work/conf/containers.conf" ]; then
  export CONTAINERS_CONF="$_here/.work/conf/containers.conf" CONTAINERS_STORAGE_CONF="$_here/.work/conf/storage.conf"
fi
if [ "$ENGINE" = docker ]; then
  COMPOSE="docker compose"
elif command -v podman-compose >/dev/null 2>&1; then
  COMPOSE=podman-compose
elif [ -x "$_here/.work/venv/bin/podman-compose" ]; then
  COMPOSE="$_here/.work/venv/bin/podman-compose"
else
  COMPOSE=""
fi
export ENGINE COMPOSE
