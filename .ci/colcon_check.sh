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
EXECUTABLES=(sim_bridge pd_gravity_controller inverse_dynamics_controller trajectory_generator recorder jsc)

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
for f in \
  "share/ament_index/resource_index/packages/$PKG" \
  "share/$PKG/package.xml" \
  "share/$PKG/urdf/planar_2dof.urdf"; do
  [[ -f "$PREFIX/$f" ]] || missing+=("$f")
done
# The Python packages themselves, with the URDF shipped as package data.
site=("$PREFIX"/lib/python3*/site-packages)
for f in "$PKG/__init__.py" "$PKG/robots/urdf/planar_2dof.urdf" "sim_bridge/__init__.py"; do
  [[ -f "${site[0]}/$f" ]] || missing+=("lib/python3.*/site-packages/$f")
done

if ((${#missing[@]})); then
  echo "colcon-check: FAILED: missing under $PREFIX:" >&2
  printf '  - %s\n' "${missing[@]}" >&2
  exit 1
fi
echo "colcon-check: OK ($PREFIX: ${EXECUTABLES[*]} in lib/$PKG, ament index, package.xml, urdf)"
