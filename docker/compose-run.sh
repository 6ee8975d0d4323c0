#!/usr/bin/env bash
# Run the node graph as containers (docker/compose.yaml) and end with the graph's exit status.
#   docker/compose-run.sh [--out DIR] [--domain-id N] [--project NAME] [--user-sut | --fiss-sut]
#                         [--bv-containers per-node|one] [--keep] [-- SCENARIO-OPTIONS...]
# SCENARIO-OPTIONS are graph_node.py's (run_scenario.py's): --steps N --seed S --sut NAME --bvs N
# --mix C:M:K --bv-nodes P --config FILE (a path inside the image) --no-plots ... (default: --steps 3000 --seed 0).
# --user-sut: the SUT is the container built from examples/ instead of evoscen's SUT node.
# --fiss-sut: the SUT is the fiss plug-in (FISS+, fiss-planner) in its own container (service
# fiss-sut); adds --sut fiss, and every node runs the fiss image (EVOSCEN_IMAGE, default
# localhost/evoscen-fiss:latest: every node checks the scenario, whose sut.model is fiss).
# --bv-containers: per-node (default) runs one container per BV node of the default partition
# (bvs.nodes by_policy with the three learned policies: bv-competitive, bv-mutual, bv-cooperative);
# one runs every BV node of the scenario in one container (service bv): any other partition. With
# --bv-nodes other than by_policy among the options, one is the default.
# Status (as run_scenario.py --mode graph): 2 bad input (any node's), 4 a node died (its container
# was killed by a signal: named in one line; the simulation's deadline abort is its consequence),
# else the simulation's exit code, else the first failing node's. Each node's is printed.
# The bag is DIR/bag, the report DIR/report (DIR default runs/compose).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd); root=$(dirname "$here")
. "$here/engine.sh"
if [ -z "$COMPOSE" ]; then
  echo "error: no compose tool for $ENGINE: install podman-compose (docker/setup-podman.sh does) or the docker compose plugin" >&2
  exit 2
fi
out=$root/runs/compose; domain=; user_sut=0; fiss_sut=0; keep=0; scen=(); proj=; bvc=
while [ $# -gt 0 ]; do
  case $1 in
    --out) out=$(realpath -m "$2"); shift 2 ;;
    --domain-id) domain=$2; shift 2 ;;
    --project) proj=$2; shift 2 ;;
    --user-sut) user_sut=1; shift ;;
    --fiss-sut) fiss_sut=1; shift ;;
    --bv-containers)
      bvc=${2:-}
      case $bvc in per-node|one) ;; *) echo "error: docker/compose-run.sh: --bv-containers '$bvc': expected per-node or one" >&2; exit 2 ;; esac
      shift 2 ;;
    --keep) keep=1; shift ;;
    --) shift; scen=("$@"); break ;;
    *) echo "error: docker/compose-run.sh: unknown option '$1' (expected --out, --domain-id, --project, --user-sut, --fiss-sut, --bv-containers, --keep, -- ...)" >&2; exit 2 ;;
  esac
done
if [ $user_sut = 1 ] && [ $fiss_sut = 1 ]; then
  echo "error: docker/compose-run.sh: --user-sut and --fiss-sut: expected at most one of them (one SUT per graph)" >&2; exit 2
fi
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
steps=3000; bv_nodes=by_policy
for ((i=0; i<${#scen[@]}; i++)); do
  case ${scen[$i]} in
    --steps) steps=${scen[$((i+1))]:-$steps} ;; --steps=*) steps=${scen[$i]#--steps=} ;;
    --bv-nodes) bv_nodes=${scen[$((i+1))]:-$bv_nodes} ;; --bv-nodes=*) bv_nodes=${scen[$i]#--bv-nodes=} ;;
  esac
done
# the BV containers: one per BV node of the default partition, or one for all BV nodes
[ -n "$bvc" ] || { [ "$bv_nodes" = by_policy ] && bvc=per-node || bvc=one; }
if [ $bvc = per-node ]; then bv_profile=bv-by-policy; bv_services=(bv-competitive bv-mutual bv-cooperative)
else bv_profile=bv-one; bv_services=(bv); fi
profile=builtin-sut
if [ $user_sut = 1 ]; then profile=user-sut; scen+=(--external-sut); fi
if [ $fiss_sut = 1 ]; then
  profile=fiss-sut; scen+=(--sut fiss); export EVOSCEN_IMAGE=${EVOSCEN_IMAGE:-${EVOSCEN_FISS_IMAGE:-localhost/evoscen-fiss:latest}}
fi
profiles=(--profile "$profile" --profile "$bv_profile")
mkdir -p "$out"
uid=$(id -u); gid=$(id -g)
if [ "$uid" = 0 ]; then uid=10001; gid=10001; chown "$uid:$gid" "$out"; fi  # the nodes never run as root
[ -n "$proj" ] || proj=evoscen-$domain-$$
shm=$(mktemp -d /dev/shm/evoscen-shm-XXXXXX); chmod 1777 "$shm"   # this graph's shared memory (compose.yaml)
export EVOSCEN_SHM_DIR=$shm EVOSCEN_OUT=$out EVOSCEN_DOMAIN_ID=$domain EVOSCEN_UID=$uid EVOSCEN_GID=$gid EVOSCEN_STEPS=$steps
export EVOSCEN_GRAPH_ARGS="${scen[*]}"
echo "compose-run: $ENGINE, project $proj, ROS_DOMAIN_ID=$domain, BV containers: ${bv_services[*]}, out $out, options: $EVOSCEN_GRAPH_ARGS" >&2
cleanup() {
  [ $keep = 1 ] || $COMPOSE -p "$proj" -f "$here/compose.yaml" "${profiles[@]}" down -v >/dev/null 2>&1 || true
  rm -rf "$shm"
}
trap cleanup EXIT
$COMPOSE -p "$proj" -f "$here/compose.yaml" "${profiles[@]}" up --no-color >"$out/compose.log" 2>&1 9>&- &
upid=$!
interrupted=0
trap 'interrupted=1; kill -INT $upid 2>/dev/null || true' INT TERM
while ! wait $upid; do [ -d /proc/$upid ] || break; done  # wait again after a trapped signal
# the nodes' exit codes, read from the engine (compose's own status differs between tools)
sut_service=sut; [ $user_sut = 1 ] && sut_service=user-sut; [ $fiss_sut = 1 ] && sut_service=fiss-sut
who() {  # the ROS 2 node a service runs, and its container
  case $1 in sim|eval|sut) echo "node evoscen_$1 (container $1)" ;; fiss-sut) echo "node evoscen_sut (container $1)" ;; bv-*) echo "node evoscen_bv_${1#bv-} (container $1)" ;;
    bv) echo "container bv (every BV node of the scenario)" ;; *) echo "the user's SUT node (container $1)" ;; esac
}
status=0; first_fail=""; bad_input=0; killed=""
for svc in sim eval "${bv_services[@]}" $sut_service; do
  ids=$($ENGINE ps -a -q --filter "label=com.docker.compose.project=$proj" --filter "label=com.docker.compose.service=$svc")
  if [ -z "$ids" ]; then
    echo "node $svc: no container (the graph did not start: see $out/compose.log)" >&2
    [ "$svc" = sim ] && status=1
    continue
  fi
  code=$($ENGINE inspect --format '{{.State.ExitCode}}' $ids | head -1)
  echo "node $svc: exit $code" >&2
  [ "$code" = 2 ] && bad_input=1
  # killed by a signal: the container's end is 128 + the signal (137: SIGKILL); no node exits so
  # by itself (its statuses are 0, 2, 3, 5, 130), and 130 is an interruption, not a death
  if [[ $code =~ ^[0-9]+$ ]] && [ "$code" -gt 128 ] && [ "$code" != 130 ] && [ -z "$killed" ]; then
    sig=$(kill -l $((code - 128)) 2>/dev/null || echo "signal $((code - 128))")
    killed="$(who "$svc") was killed by SIG${sig#SIG} (exit code $code)"
  fi
  if [ "$svc" = sim ]; then status=$code; elif [ "$code" != 0 ] && [ -z "$first_fail" ]; then first_fail=$code; fi
done
[ "$status" = 0 ] && [ -n "$first_fail" ] && status=$first_fail
if [ $bad_input = 1 ]; then
  status=2   # bad input: any fault that followed is its consequence
elif [ -n "$killed" ] && [ $interrupted = 0 ]; then
  # a node died: the simulation's deadline abort (3) is its consequence (run_scenario.py: the same)
  status=4; echo "error: compose-run: $killed; the run ended early (exit status 4)" >&2
fi
if [ -f "$out/report/report.json" ]; then
  python3 -c 'import json, sys; r = json.load(open(sys.argv[1])); print("intelligence: %.4f  complexity: %s  SUT collisions: %d  exposures: %d" % (r["intelligence"]["score"], "-" if r["complexity"]["score"] is None else "%.4f" % r["complexity"]["score"], r["safety"]["collisions"], r["safety"]["exposures"]))' "$out/report/report.json"
  echo "report: $out/report/report.md"
fi
echo "compose-run: graph status $status; bag $out/bag; log $out/compose.log" >&2
exit "$status"
