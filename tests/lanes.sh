#!/usr/bin/env bash
# Every test of the workspace (`cargo test --workspace`: unit, integration and doc tests),
# in two lanes side by side, then the tests that must have the machine to themselves.
#
# Most of skein's end-to-end tests fly simulated vehicles in real time and wait on them:
# run one after another they keep a 2-core machine about a fifth busy. Two lanes at once
# halve the wall time. Test targets are split between the lanes by their duration on the
# 2-core CI machine (LANE_A below; everything else goes to lane B), and those in ALONE run
# after both lanes, one at a time (e2e_overload starves skein of CPU on purpose and
# measures how it copes: another test's load would change what it measures; e2e_tracking
# ranges five intruders from two cameras, and with them 5 m apart, short of CPU, it made
# more tracks at wrong ranges (rays of two aircraft crossing): with two busy loops beside
# it, its hostile swarm of five was whole in one run of two, and once in CI beside lane
# B, never; the test now spreads the cameras 20 m apart first, but keeps the machine;
# e2e_wlan flies five processes under DDS Security through a lossy WLAN: beside lane B
# every process ran 40-60 ms late in its bad-WLAN phase and the formation's RMS p95
# reached 1.92 m, once in CI; e2e_formation flies eight simulated PX4s at 50 Hz, most of
# two cores in a debug build, and measures the wedge's slot error at 5 m/s: beside lane B
# its skein ran 48 ms late and the error climbed to 0.47 m RMS (0.15-0.19 m alone), once in
# CI; bench_smoke runs the benchmarks, whose figures are the machine's when they have it:
# beside lane A the tracking bench fell short in two CI runs in a row (its cameras made 66,
# then 17 frames in 15 s: too few track samples, then no track error at all);
# e2e_distributed runs a coordinator (two, in its mission failover) and three agents with
# their simulators, each a debug process: in lane A, once its mission failover was added,
# lane B's DDS bench beside it timed out listing its vehicles and the Mission view test's
# rehearsal (at nice 19, 4 s of CPU alone) did not end within 300 s, once in CI);
# e2e_assembly starts seventeen agents (each a debug process with its simulator) and a
# coordinator at once under DDS Security: more than the two cores while they assemble;
# peers drives the dashboard in Chromium against flying simulators and the counter-UAS
# camera pipeline: in lane B, after lane A had ended, beside the idle-priority builds,
# its hostile swarm never formed on the plan once (as e2e_tracking's did beside them),
# and once a vehicle of its mission ended in PX4's HOLD failsafe while landing (two CI
# runs in a row, 2026-11-29; both passed in every run before).
#
# Two builds run beside all of it at idle priority (SCHED_IDLE: they get only the CPU no
# test wants), but for e2e_tracking, e2e_wlan, e2e_formation, peers and bench_smoke, during which
# they are stopped: the arm64 cross-build (deploy_arm64 waits for it) and the fuzz targets'
# (tests/fuzz.sh runs them afterwards).
#
# Tests that share something run in the same lane or keep it apart themselves: DDS
# domains are derived from the test process id in disjoint ranges per target, network
# namespaces and ports are per process, and the plugin builds take a file lock.
# Each lane's output is prefixed with its name; a lane's failure fails the run after both
# lanes end (both run to the end: one red lane does not hide the other's results).
set -euo pipefail
cd "$(dirname "$0")/.."

LANE_A=(e2e_hazards deploy_compose e2e_dds_security e2e_missions)
# deploy_arm64 runs the arm64 build made beside the lanes (below), so after them.
ALONE=(e2e_distributed e2e_assembly e2e_tracking e2e_overload e2e_wlan e2e_formation peers bench_smoke deploy_arm64)

# Build everything first, once: the lanes then only run.
cargo test --workspace --locked --no-run

# The arm64 cross-build of skein and its plugins (deploy_arm64's; about 5 min of CPU) runs
# beside the lanes, which leave most of the two cores idle, at idle priority (SCHED_IDLE:
# it gets the CPU only when no test wants it), in a target directory of its own (so no
# lane waits for its lock). deploy_arm64 finds it built; had it failed, deploy_arm64
# builds again and says why.
arm64_log=target/arm64-build.log
mkdir -p target
setsid chrt --idle 0 nice -n 19 deploy/docker/cross-build.sh --profile arm64-test --target-dir "$PWD/target/arm64" \
  >"$arm64_log" 2>&1 &
pid_arm64=$!
# The fuzz targets' build (tests/fuzz.sh runs them after this script; cargo-fuzz's install
# and a second, instrumented build of the API, the link and the video decoder: minutes of
# CPU) beside them too, the same way; fuzz.sh then finds them built, or builds again and
# says why.
fuzz_log=target/fuzz-build.log
setsid chrt --idle 0 nice -n 19 tests/fuzz.sh --build-only >"$fuzz_log" 2>&1 &
pid_fuzz=$!

mapfile -t all_tests < <(cargo metadata --no-deps --format-version 1 --locked |
  python3 -c 'import json, sys
for p in json.load(sys.stdin)["packages"]:
    for t in p["targets"]:
        if "test" in t["kind"]:
            print(t["name"])')

in_list() { # name list...
  local n=$1
  shift
  for x in "$@"; do [ "$x" = "$n" ] && return 0; done
  return 1
}
lane_a=()
lane_b=(--lib --bins)
for t in "${all_tests[@]}"; do
  if in_list "$t" "${LANE_A[@]}"; then
    lane_a+=(--test "$t")
  elif ! in_list "$t" "${ALONE[@]}"; then
    lane_b+=(--test "$t")
  fi
done
for t in "${LANE_A[@]}" "${ALONE[@]}"; do
  in_list "$t" "${all_tests[@]}" || { echo "tests/lanes.sh: no test target $t" >&2; exit 2; }
done

# `lane NAME CARGO-TEST-ARGS...`: cargo test with the lane's name before every line.
lane() {
  local name=$1
  shift
  cargo test --workspace --locked --no-fail-fast "$@" 2>&1 | sed -u "s/^/[$name] /"
  return "${PIPESTATUS[0]}"
}
started=$(date +%s)
(
  rc=0
  lane a "${lane_a[@]}" || rc=$?
  echo "tests/lanes.sh: lane a done in $(($(date +%s) - started)) s" >&2
  exit "$rc"
) &
pid_a=$!
(
  rc=0
  lane b "${lane_b[@]}" || rc=$?
  lane b --doc || rc=$?
  echo "tests/lanes.sh: lane b done in $(($(date +%s) - started)) s" >&2
  exit "$rc"
) &
pid_b=$!
failed=""
wait "$pid_a" || failed="$failed a"
wait "$pid_b" || failed="$failed b"
echo "tests/lanes.sh: lanes done in $(($(date +%s) - started)) s" >&2
# The tests in ALONE do not wait for the idle-priority builds, which go on beside them
# (they take only what those tests leave idle), but for deploy_arm64, which needs one;
# e2e_tracking, e2e_wlan, e2e_formation, peers and bench_smoke have the machine to themselves:
# the builds (each its own process group, by setsid) are stopped while they run and
# continued after.
# Beside them, once, e2e_tracking found no hostile swarm (its image processing is short of
# CPU before anything else), and e2e_wlan failed in two CI runs of four and passed alone:
# an agent's stream paused 123 ms while its process ran 41 ms late, and a member ended
# 7.6 m off its slot after a failover. Stopping the builds costs their 3 minutes at the
# end of the run.
builds() { # STOP|CONT: every idle-priority build still running
  local p
  for p in "$pid_arm64" "$pid_fuzz"; do kill "-$1" -- "-$p" 2>/dev/null || true; done
}
for t in "${ALONE[@]}"; do
  case $t in e2e_tracking | e2e_wlan | e2e_formation | peers | bench_smoke) builds STOP ;; esac
  if [ "$t" = deploy_arm64 ]; then
    if wait "$pid_arm64"; then
      echo "tests/lanes.sh: arm64 cross-build done in $(($(date +%s) - started)) s" >&2
    else
      echo "tests/lanes.sh: the arm64 cross-build failed (target/arm64-build.log)" >&2
    fi
  fi
  cargo test --workspace --locked --test "$t" || failed="$failed $t"
  case $t in e2e_tracking | e2e_wlan | e2e_formation | peers | bench_smoke) builds CONT ;; esac
done
if wait "$pid_fuzz"; then
  echo "tests/lanes.sh: fuzz build done in $(($(date +%s) - started)) s" >&2
else
  echo "tests/lanes.sh: the fuzz build failed (target/fuzz-build.log); fuzz.sh builds again" >&2
fi
if [ -n "$failed" ]; then
  echo "tests/lanes.sh: failed:$failed (search the log for its lane's prefix)" >&2
  exit 101
fi
