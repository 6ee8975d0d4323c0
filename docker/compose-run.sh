#!/usr/bin/env bash
# Run the node graph as containers (docker/compose.yaml) and end with the graph's exit status.
#   docker/compose-run.sh [--out DIR] [--domain-id N] [--project NAME] [--user-sut] [--keep] [-- SCENARIO-OPTIONS...]
# SCENARIO-OPTIONS are graph_node.py's (run_scenario.py's): --steps N --seed S --sut NAME --bvs N
# --mix C:M:K --config FILE (a path inside the image) --no-plots ... (default: --steps 3000 --seed 0).
# --user-sut: the SUT is the container built from examples/ instead of evoscen's SUT node.
# Status: the simulation's exit code, else the first failing node's (as run_scenario.py --mode graph);
# each node's is printed. The bag is DIR/bag, the report DIR/report (DIR default runs/compose).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd); root=$(dirname "$here")
. "$here/engine.sh"
if [ -z "$COMPOSE" ]; then
  echo "error: no compose tool for $ENGINE: install podman-compose (docker/setup-podman.sh does) or the docker compose plugin" >&2
  exit 2
fi
out=$root/runs/compose; domain=; user_sut=0; keep=0; scen=(); proj=
while [ $# -gt 0 ]; do
  case $1 in
    --out) out=$(realpath -m "$2"); shift 2 ;;
    --domain-id) domain=$2; shift 2 ;;
    --project) proj=$2; shift 2 ;;
    --user-sut) user_sut=1; shift ;;
    --keep) keep=1; shift ;;
    --) shift; scen=("$@"); break ;;
    *) echo "error: docker/compose-run.sh: unknown option '$1' (expected --out, --domain-id, --project, --user-sut, --keep, -- ...)" >&2; exit 2 ;;
  esac
done
# the domain is reserved on this host like the native launcher's (evoscen_bringup/domains.py):
# an exclusive flock on the same lock file, held on fd 9 until this script ends
lockdir=${EVOSCEN_DOMAIN_LOCK_DIR:-${TMPDIR:-/tmp}/evoscen-domains}
mkdir -p "$lockdir" && { chmod 1777 "$lockdir" 2>/dev/null || true; }
reserve() { exec 9<>"$lockdir/domain-$1.lock" && { chmod 666 "$lockdir/domain-$1.lock" 2>/dev/null || true; } && flock -n 9; }
if [ -n "$domain" ]; then
  reserve "$domain" || { echo "error: docker/compose-run.sh: --domain-id $domain: another evoscen graph on this host runs on ROS_DOMAIN_ID $domain (lock $lockdir/domain-$domain.lock); choose another domain or leave --domain-id out" >&2; exit 2; }
else
  for d in $(shuf -i 1-100); do if reserve "$d"; then domain=$d; break; fi; exec 9>&-; done
  [ -n "$domain" ] || { echo "error: docker/compose-run.sh: no free ROS_DOMAIN_ID in 1..100 (locks in $lockdir)" >&2; exit 2; }
fi
[ ${#scen[@]} -eq 0 ] && scen=(--steps 3000 --seed 0)
steps=3000; for ((i=0; i<${#scen[@]}-1; i++)); do [ "${scen[$i]}" = --steps ] && steps=${scen[$((i+1))]}; done
profile=builtin-sut
if [ $user_sut = 1 ]; then profile=user-sut; scen+=(--external-sut); fi
mkdir -p "$out"
uid=$(id -u); gid=$(id -g)
if [ "$uid" = 0 ]; then uid=10001; gid=10001; chown "$uid:$gid" "$out"; fi  # the nodes never run as root
[ -n "$proj" ] || proj=evoscen-$domain-$$
shm=$(mktemp -d /dev/shm/evoscen-shm-XXXXXX); chmod 1777 "$shm"   # this graph's shared memory (compose.yaml)
export EVOSCEN_SHM_DIR=$shm EVOSCEN_OUT=$out EVOSCEN_DOMAIN_ID=$domain EVOSCEN_UID=$uid EVOSCEN_GID=$gid EVOSCEN_STEPS=$steps
export EVOSCEN_GRAPH_ARGS="${scen[*]}"
echo "compose-run: $ENGINE, project $proj, ROS_DOMAIN_ID=$domain, out $out, options: $EVOSCEN_GRAPH_ARGS" >&2
cleanup() {
  [ $keep = 1 ] || $COMPOSE -p "$proj" -f "$here/compose.yaml" --profile "$profile" down -v >/dev/null 2>&1 || true
  rm -rf "$shm"
}
trap cleanup EXIT
$COMPOSE -p "$proj" -f "$here/compose.yaml" --profile "$profile" up --no-color >"$out/compose.log" 2>&1 9>&- &
upid=$!
trap 'kill -INT $upid 2>/dev/null || true' INT TERM
wait $upid || true
# the nodes' exit codes, read from the engine (compose's own status differs between tools)
sut_service=sut; [ $user_sut = 1 ] && sut_service=user-sut
status=0; first_fail=""
for svc in sim eval bv $sut_service; do
  ids=$($ENGINE ps -a -q --filter "label=com.docker.compose.project=$proj" --filter "label=com.docker.compose.service=$svc")
  if [ -z "$ids" ]; then
    echo "node $svc: no container (the graph did not start: see $out/compose.log)" >&2
    [ "$svc" = sim ] && status=1
    continue
  fi
  code=$($ENGINE inspect --format '{{.State.ExitCode}}' $ids | head -1)
  echo "node $svc: exit $code" >&2
  if [ "$svc" = sim ]; then status=$code; elif [ "$code" != 0 ] && [ -z "$first_fail" ]; then first_fail=$code; fi
done
[ "$status" = 0 ] && [ -n "$first_fail" ] && status=$first_fail
if [ -f "$out/report/report.json" ]; then
  python3 -c 'import json, sys; r = json.load(open(sys.argv[1])); print("intelligence: %.4f  complexity: %s  SUT collisions: %d  exposures: %d" % (r["intelligence"]["score"], "-" if r["complexity"]["score"] is None else "%.4f" % r["complexity"]["score"], r["safety"]["collisions"], r["safety"]["exposures"]))' "$out/report/report.json"
  echo "report: $out/report/report.md"
fi
echo "compose-run: graph status $status; bag $out/bag; log $out/compose.log" >&2
exit "$status"
