"""A description that looks like a floating-base robot but has no floating joint is loaded
fixed with one warning that says so (issue 26, item 7): Go1 and Talos of example-robot-data
are, Baxter (several chains, no feet) and every corpus arm are not."""

from __future__ import annotations

import pytest

from joint_space_control.model.robots import resolve_robot
from test.corpus import CORPUS, PACKAGE_PATHS, ROBOTS

HINT = "looks like a floating-base robot"


def hints(path: str) -> list[str]:
    spec = resolve_robot(urdf_path=str(ROBOTS / path), package_paths=PACKAGE_PATHS)
    return [w for w in spec.warnings if HINT in w]


@pytest.mark.parametrize(
    ("path", "feet", "root"),
    [
        ("go1_description/urdf/go1.urdf", "4 kinematic chains end in feet", "'base'"),
        ("talos_data/robots/talos_full_v2.urdf", "2 kinematic chains end in feet", "'base_link'"),
    ],
)
def test_legged_descriptions_without_a_floating_joint_are_said_fixed(path, feet, root):
    (line,) = hints(path)
    assert feet in line and f"root link {root} fixed in the world" in line
    assert "give its root a floating joint" in line  # how to have it refused
    assert "\n" not in line


def test_arms_and_a_torso_with_arms_get_no_such_warning():
    assert hints("baxter_description/urdf/baxter.urdf") == []
    for robot in CORPUS:
        spec = resolve_robot(**robot.params())
        assert not [w for w in spec.warnings if HINT in w], robot.name
