#!/usr/bin/env bash
# Build joint_space_control with colcon in a throwaway workspace and check the layout that
# `ros2 run` and the ament index rely on (INTERFACES.md, "Package").
#
#   COLCON  colcon executable      (default: .venv/bin/colcon, from colcon-common-extensions)
#   WS      workspace to (re)create (default: build/colcon_ws)
#
# No ROS install or AMENT_PREFIX_PATH is needed: colcon-ros (PyPI) builds ament_python
# packages by running setup.py with colcon's own Python.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
COLCON="${COLCON:-$ROOT/.venv/bin/colcon}"
WS="${WS:-$ROOT/build/colcon_ws}"
PKG=joint_space_control
EXECUTABLES=(sim_bridge pd_gravity_controller inverse_dynamics_controller trajectory_generator recorder dashboard jsc)

if [[ ! -x "$COLCON" && "$COLCON" != */* ]]; then
  COLCON="$(command -v "$COLCON" || echo "$COLCON")"
fi
[[ -x "$COLCON" ]] || {
  echo "colcon-check: FAILED: colcon not found at '$COLCON' (run 'make venv')" >&2
  exit 1
}
COLCON="$(cd "$(dirname "$COLCON")" && pwd)/$(basename "$COLCON")"

# Fresh workspace whose src/ holds the package through a symlink, as a user's checkout would.
rm -rf "$WS"
mkdir -p "$WS/src"
ln -s "$ROOT" "$WS/src/$PKG"

echo "colcon-check: building $PKG in $WS"
(
  cd "$WS"
  # Private COLCON_HOME: a developer's ~/.colcon/defaults.yaml must not change this build.
  COLCON_HOME="$WS/.colcon" "$COLCON" --log-base log build \
    --base-paths src \
    --build-base build \
    --install-base install \
    --packages-select "$PKG" \
    --event-handlers console_direct+
) || { echo "colcon-check: FAILED: colcon build exited non-zero (logs: $WS/log)" >&2; exit 1; }

PREFIX="$WS/install/$PKG"
missing=()
for exe in "${EXECUTABLES[@]}"; do
  [[ -f "$PREFIX/lib/$PKG/$exe" && -x "$PREFIX/lib/$PKG/$exe" ]] \
    || missing+=("lib/$PKG/$exe (executable)")
done
# Here they are the console scripts themselves (setup.cfg), run by colcon's Python: not the
# wheel's launchers (resource/launchers/, which run <prefix>/bin/<exe>, absent in colcon).
for exe in "${EXECUTABLES[@]}"; do
  f="$PREFIX/lib/$PKG/$exe"
  if [[ -f "$f" ]] && ! head -n 1 "$f" | grep -q '^#!.*python'; then
    missing+=("lib/$PKG/$exe as a console script (found: $(head -n 1 "$f"))")
  fi
done
for f in \
  "share/ament_index/resource_index/packages/$PKG" \
  "share/$PKG/package.xml" \
  "share/$PKG/launch/sim.launch.py" \
  "share/$PKG/launch/controllers.launch.py" \
  "share/$PKG/config/sim_bridge.yaml" \
  "share/$PKG/config/experiments/q6_inverse_dynamics_nominal.yaml" \
  "share/$PKG/urdf/planar_2dof.urdf"; do
  [[ -f "$PREFIX/$f" ]] || missing+=("$f")
done
# The Python packages themselves, with the configs and the URDF shipped as package data
# (what the code reads, through importlib.resources: joint_space_control/paths.py).
site=("$PREFIX"/lib/python3*/site-packages)
for f in "$PKG/__init__.py" "$PKG/config/sim_bridge.yaml" \
  "$PKG/config/experiments/q6_inverse_dynamics_nominal.yaml" \
  "$PKG/robots/urdf/planar_2dof.urdf" "sim_bridge/__init__.py"; do
  [[ -f "${site[0]}/$f" ]] || missing+=("lib/python3.*/site-packages/$f")
done

if ((${#missing[@]})); then
  echo "colcon-check: FAILED: missing under $PREFIX:" >&2
  printf '  - %s\n' "${missing[@]}" >&2
  exit 1
fi
# The installed package finds its scenarios by itself: imported from the install (not the
# checkout, not a sourced workspace) with colcon's Python, the one that built it.
PY="$(dirname "$COLCON")/python3"
if [[ -x "$PY" ]]; then
  (cd "$WS" && env -u AMENT_PREFIX_PATH PYTHONPATH="${site[0]}" "$PY" -c '
import sys
import joint_space_control
from joint_space_control.workbench.experiments.scenarios.format import available
site = sys.argv[1]
assert joint_space_control.__file__.startswith(site), joint_space_control.__file__
found = available()
assert "q6_inverse_dynamics_nominal" in found, sorted(found)
assert all(str(p).startswith(site) for p in found.values()), found
' "${site[0]}") || {
    echo "colcon-check: FAILED: the installed package does not find its scenarios" >&2
    exit 1
  }
fi
echo "colcon-check: OK ($PREFIX: ${EXECUTABLES[*]} in lib/$PKG, ament index, package.xml, launch, config, urdf, package data)"
