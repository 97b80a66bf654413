#!/usr/bin/env bash
# Build the wheel, install it with its PyPI dependencies into a fresh virtual environment
# and run the user-facing commands from outside the checkout, the way a user of
# `pip install '.[pypi]'` would (issue 12: only the editable install found the package data).
#
#   BUILD_PY  python that builds the wheel (pip + setuptools)  (default: .venv/bin/python)
#   PYTHON    python that creates the fresh venv               (default: python3.11 or python3)
#   OUT       work directory, recreated                        (default: build/wheel_check)
#
# The fresh venv is not --system-site-packages and the commands run with a clean
# environment (no PYTHONPATH, no AMENT_PREFIX_PATH, not in the checkout), so neither the
# source tree nor a sourced ROS install can stand in for what the wheel ships.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_PY="${BUILD_PY:-$ROOT/.venv/bin/python}"
PYTHON="${PYTHON:-$(command -v python3.11 || command -v python3)}"
OUT="${OUT:-$ROOT/build/wheel_check}"
VENV="$OUT/venv"
# Marks every process the checked commands start (node processes inherit the environment),
# so leftovers are found exactly, and only ours.
TOKEN="jsc-wheel-check-$$-$RANDOM"
started=$SECONDS
RUN=""

fail() {
  echo "wheel-check: FAILED: $*" >&2
  exit 1
}

# PIDs of processes started under this check that are still alive.
marked_pids() {
  local environ pid
  for environ in /proc/[0-9]*/environ; do
    pid="${environ#/proc/}"
    pid="${pid%/environ}"
    [[ "$pid" == "$$" ]] && continue
    if grep -qzx "JSC_WHEEL_CHECK=$TOKEN" "$environ" 2>/dev/null; then
      echo "$pid"
    fi
  done
}

# Stop what the checked commands left running: SIGTERM, then SIGKILL after 5 s.
stop_leftovers() {
  local pids pid
  pids="$(marked_pids)"
  [[ -z "$pids" ]] && return 0
  for pid in $pids; do kill -TERM "$pid" 2>/dev/null || true; done
  for _ in $(seq 50); do
    pids="$(marked_pids)"
    [[ -z "$pids" ]] && return 0
    sleep 0.1
  done
  for pid in $pids; do kill -KILL "$pid" 2>/dev/null || true; done
}

cleanup() {
  local status=$?
  stop_leftovers
  if [[ -n "$RUN" ]]; then
    if ((status == 0)); then rm -rf "$RUN"; else echo "wheel-check: outputs kept in $RUN" >&2; fi
  fi
  exit "$status"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

[[ -x "$BUILD_PY" ]] || fail "no python at '$BUILD_PY' to build the wheel (run 'make venv')"
[[ -n "$PYTHON" && -x "$PYTHON" ]] || fail "no python3.11 or python3 for the fresh venv"

rm -rf "$OUT"
mkdir -p "$OUT"

echo "wheel-check: building the wheel"
# setuptools stages the wheel in build/lib and build/bdist.*: stale files there (a module
# deleted since the last build) would end up in the wheel.
rm -rf "$ROOT/build/lib" "$ROOT"/build/bdist.*
(cd "$ROOT" && "$BUILD_PY" -m pip wheel --no-deps -w "$OUT/wheel" . >"$OUT/wheel.log" 2>&1) \
  || { cat "$OUT/wheel.log" >&2; fail "pip wheel"; }
wheels=("$OUT"/wheel/joint_space_control-*.whl)
[[ -f "${wheels[0]}" ]] || fail "no wheel in $OUT/wheel"
WHEEL="${wheels[0]}"

echo "wheel-check: installing $(basename "$WHEEL")[pypi] into a fresh venv ($VENV)"
"$PYTHON" -m venv "$VENV"
"$VENV/bin/python" -m pip install "$WHEEL[pypi]" >"$OUT/pip.log" 2>&1 \
  || { tail -n 40 "$OUT/pip.log" >&2; fail "pip install $WHEEL[pypi] (log: $OUT/pip.log)"; }

RUN="$(mktemp -d "${TMPDIR:-/tmp}/jsc-wheel-check.XXXXXX")"
# A ROS domain outside the 1..100 that jsc leases to its runs (valid ids go up to 232;
# 215..232 keep the ports above Linux's ephemeral range): anything that would otherwise use
# the default domain 0 meets neither interactive ROS users nor other runs. The jsc commands
# themselves lease a domain no other run on the machine holds.
DOMAIN=$((215 + RANDOM % 18))

# One command as a user in a fresh shell: in $RUN, a minimal environment, a time limit.
check() {
  local what="$1" limit="$2"
  shift 2
  local t0=$SECONDS
  echo "wheel-check: \$ $(head -n 1 <<<"$*")"
  if ! (cd "$RUN" && env -i \
    PATH="$VENV/bin:/usr/local/bin:/usr/bin:/bin" \
    HOME="${HOME:-$RUN}" LANG=C.UTF-8 TMPDIR="${TMPDIR:-/tmp}" \
    ROS_DOMAIN_ID="$DOMAIN" ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST \
    JSC_WHEEL_CHECK="$TOKEN" \
    timeout --kill-after=10 "$limit" "$@" >"$RUN/$what.log" 2>&1); then
    tail -n 40 "$RUN/$what.log" >&2
    fail "'$*' (log: $RUN/$what.log)"
  fi
  # jsc stops its node processes before it exits; anything still running is a leak.
  sleep 1
  local left
  left="$(marked_pids)"
  if [[ -n "$left" ]]; then
    ps -o pid,args -p "$(echo "$left" | paste -sd,)" >&2 || true
    fail "'$*' left processes running"
  fi
  echo "wheel-check:   ok ($((SECONDS - t0)) s)"
}

# The package must come from the venv, not from a checkout.
check import 60 python -c 'import sys, joint_space_control as j, sim_bridge as s
bad = [m.__file__ for m in (j, s) if not m.__file__.startswith(sys.prefix)]
sys.exit(f"imported from outside the venv: {bad}" if bad else 0)'
# The product alone: no cluster scheduler, no optimiser; the workbench's commands say what
# they need in one line.
if "$VENV/bin/python" -c 'import importlib.util as u, sys; sys.exit(any(u.find_spec(m) for m in ("dask", "optuna")))'; then
  echo "wheel-check:   ok: [pypi] installs neither dask nor optuna"
else
  fail "pip install $WHEEL[pypi] installed dask or optuna (the workbench's)"
fi
check simulate 120 python -c 'from joint_space_control.simulation import simulate
r = simulate("planar_2dof", "pd_gravity", target=[0.5, -0.3], duration=2.0)
assert abs(r.q[-1] - [0.5, -0.3]).max() < 1e-3, r.q[-1]'
# `ros2 run joint_space_control <exe>` and launch files look in <prefix>/lib/joint_space_control/
# (ament index: share/ament_index/resource_index/packages/joint_space_control): the wheel puts
# a launcher there per console script (resource/launchers/), which runs <prefix>/bin/<exe>;
# and the launch files under share/joint_space_control/launch/.
EXECUTABLES=(sim_bridge pd_gravity_controller inverse_dynamics_controller trajectory_generator recorder dashboard jsc)
[[ -f "$VENV/share/ament_index/resource_index/packages/joint_space_control" ]] \
  || fail "no ament index marker in $VENV/share/ament_index"
for f in sim.launch.py controllers.launch.py; do
  [[ -f "$VENV/share/joint_space_control/launch/$f" ]] || fail "no share/joint_space_control/launch/$f"
done
for exe in "${EXECUTABLES[@]}"; do
  launcher="$VENV/lib/joint_space_control/$exe"
  [[ -f "$launcher" && -x "$launcher" ]] || fail "no executable $launcher"
  grep -q "/\.\./\.\./bin\" .*)/$exe\"\$" "$launcher" \
    || fail "$launcher does not run bin/$exe"
  [[ -x "$VENV/bin/$exe" ]] || fail "no console script $VENV/bin/$exe for $launcher"
done
check launcher-jsc 60 "$VENV/lib/joint_space_control/jsc" --help
grep -q "jsc experiment\|usage: jsc" "$RUN/launcher-jsc.log" || fail "lib/joint_space_control/jsc --help"
# The plant through its launcher, as `ros2 run` starts it, stopped by Ctrl-C (SIGINT) after
# 10 s: it must exit 0 (--preserve-status: the node's own exit status).
check launcher-sim_bridge 60 timeout --preserve-status -s INT 10 \
  "$VENV/lib/joint_space_control/sim_bridge" --ros-args -p mode:=lockstep
grep -q "sim_bridge: planar_2dof" "$RUN/launcher-sim_bridge.log" \
  || fail "lib/joint_space_control/sim_bridge did not start the plant"
check demo 300 jsc demo --out "$RUN/demo"
[[ -f "$RUN/demo/report/report.md" ]] || fail "jsc demo wrote no report"
if (cd "$RUN" && "$VENV/bin/jsc" tune planar_2dof --controller pd_gravity --spec "overshoot<=5" \
  >"$RUN/tune-without-extra.log" 2>&1); then
  fail "jsc tune ran without the workbench extra"
fi
grep -q "needs the workbench extra" "$RUN/tune-without-extra.log" \
  || fail "jsc tune without the workbench extra: no one-line reason ($RUN/tune-without-extra.log)"
echo "wheel-check: installing the workbench extra ($(basename "$WHEEL")[pypi,workbench])"
"$VENV/bin/python" -m pip install "$WHEEL[pypi,workbench]" >>"$OUT/pip.log" 2>&1 \
  || { tail -n 40 "$OUT/pip.log" >&2; fail "pip install $WHEEL[pypi,workbench]"; }
check list 120 jsc experiment --list
grep -q '^q6_inverse_dynamics_nominal ' "$RUN/list.log" || fail "jsc experiment --list: no q6"
if grep -q INVALID "$RUN/list.log"; then fail "jsc experiment --list: invalid scenarios"; fi
check experiment 600 jsc experiment q6_inverse_dynamics_nominal --out "$RUN/experiments"
[[ -f "$RUN/experiments/q6_inverse_dynamics_nominal/summary.md" ]] \
  || fail "jsc experiment wrote no summary"

echo "wheel-check: OK ($(basename "$WHEEL"): import, [pypi] without dask/optuna, simulate()," \
  "lib/joint_space_control launchers and share/joint_space_control/launch, tune" \
  "refused without its extra, experiment --list, demo, experiment" \
  "q6_inverse_dynamics_nominal, from $RUN; $((SECONDS - started)) s)"
