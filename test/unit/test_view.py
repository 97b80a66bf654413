"""The GUI's camera frames the robots (sim_bridge/view.py), checked against PyBullet's own
view and projection matrices: every point of the scene is drawn within the asked fraction
of the picture, the picture is centred, and the camera is as close as that allows."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest

from joint_space_control.model.robots import resolve_robot
from sim_bridge.view import (
    MIN_DISTANCE,
    body_boxes,
    box_corners,
    camera_axes,
    fit_camera,
    frame_view,
    half_fov_tangents,
    primitive_box,
)

#: PyBullet's GUI: 90 deg vertical field of view, a 1024 x 768 window.
FOV, ASPECT = 90.0, 1024 / 768
TANGENTS = (ASPECT * math.tan(math.radians(FOV / 2)), math.tan(math.radians(FOV / 2)))


@pytest.fixture
def client():
    c = pb.connect(pb.DIRECT)
    yield c
    pb.disconnect(c)


def picture(points, distance, target, yaw, pitch, fov=FOV, aspect=ASPECT):
    """(x, y) of each point in normalised device coordinates (±1 at the picture's edges)
    and its depth ahead of the eye [m], with PyBullet's own matrices."""
    V = np.reshape(
        pb.computeViewMatrixFromYawPitchRoll(target, distance, yaw, pitch, 0, 2), (4, 4)
    )
    P = np.reshape(pb.computeProjectionMatrixFOV(fov, aspect, 0.01, 1000.0), (4, 4))
    h = np.c_[points, np.ones(len(points))] @ V  # row vectors: column-major matrices
    clip = h @ P
    return clip[:, :2] / clip[:, 3:], -h[:, 2]


@pytest.mark.parametrize("yaw, pitch", [(50, -35), (0, -10), (-120, 20), (270, -80)])
def test_camera_axes_are_pybullets(yaw, pitch):
    """The rows of PyBullet's view rotation are right, up and −forward."""
    V = np.reshape(pb.computeViewMatrixFromYawPitchRoll([0, 0, 0], 1.0, yaw, pitch, 0, 2), (4, 4))
    forward, right, up = camera_axes(yaw, pitch)
    np.testing.assert_allclose(V[:3, :3].T, [right, up, -forward], atol=1e-6)


def test_camera_axes_refuse_looking_straight_down():
    with pytest.raises(ValueError, match="pitch"):
        camera_axes(0.0, -90.0)


def test_half_fov_tangents_of_pybullets_projection():
    P = pb.computeProjectionMatrixFOV(FOV, ASPECT, 0.01, 1000.0)
    np.testing.assert_allclose(half_fov_tangents(P), TANGENTS, rtol=1e-6)
    t = math.tan(math.radians(30))
    np.testing.assert_allclose(
        half_fov_tangents(pb.computeProjectionMatrixFOV(60, 2.0, 0.1, 10)), (2 * t, t), rtol=1e-6
    )
    with pytest.raises(ValueError, match="perspective"):
        half_fov_tangents([0.0] * 16)  # what a DIRECT client reports


def scenes():
    rng = np.random.default_rng(17)
    tall = box_corners([((-0.14, -0.12, 0.0), (0.12, 0.14, 1.31))])  # the iiwa
    line = np.c_[np.linspace(-0.1, 2.0, 22), np.zeros(22), np.zeros(22)]  # the planar arm
    row = box_corners([((-0.1, y - 0.1, 0), (0.1, y + 0.1, 1.3)) for y in (0.0, 1.0, 2.0)])
    cloud = rng.normal(size=(200, 3)) * [3.0, 0.5, 1.0] + [5.0, -2.0, 1.0]
    return {"tall": tall, "line": line, "row": row, "cloud": cloud}


@pytest.mark.parametrize("scene", ["tall", "line", "row", "cloud"])
@pytest.mark.parametrize("yaw, pitch", [(50, -35), (0, -10), (-120, 20), (200, -70)])
@pytest.mark.parametrize("fill, ratio", [(0.85, 4.0), (1.0, 20.0), (0.5, 1.5)])
def test_fit_camera_frames_every_point_centred(scene, yaw, pitch, fill, ratio):
    """Every point is drawn within ±fill, the extremes are symmetric about the centre in
    both directions, and the camera is as close as it may be: either the picture reaches
    ±fill in one direction or the depth ratio (farthest / nearest point) is ρ. PyBullet's
    matrices are single precision: 1e-5."""
    points = scenes()[scene]
    distance, target = fit_camera(points, TANGENTS, yaw, pitch, fill, ratio)
    ndc, depth = picture(points, distance, target, yaw, pitch)
    assert np.all(depth > 0)
    assert np.max(np.abs(ndc)) <= fill + 1e-5
    np.testing.assert_allclose(ndc.max(axis=0), -ndc.min(axis=0), atol=1e-5)
    touches = math.isclose(np.max(np.abs(ndc)), fill, rel_tol=1e-5)
    assert touches or math.isclose(depth.max() / depth.min(), ratio, rel_tol=1e-5)
    assert depth.max() / depth.min() <= ratio * (1 + 1e-5)
    # the target is level with the centre of the points' bounding box
    forward = camera_axes(yaw, pitch)[0]
    centre = (points.min(axis=0) + points.max(axis=0)) / 2
    assert math.isclose((centre - target) @ forward, 0.0, abs_tol=1e-9)


def test_fit_camera_of_one_point_looks_at_it_from_the_minimum_distance():
    distance, target = fit_camera(np.array([[1.0, 2.0, 3.0]]), TANGENTS)
    assert distance == MIN_DISTANCE
    np.testing.assert_allclose(target, [1.0, 2.0, 3.0], atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, match",
    [({"fill": 0.0}, "fill"), ({"fill": 1.5}, "fill"), ({"depth_ratio": 1.0}, "depth_ratio")],
)
def test_fit_camera_rejects_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        fit_camera(np.zeros((1, 3)), TANGENTS, **kwargs)
    with pytest.raises(ValueError, match="no points"):
        fit_camera(np.empty((0, 3)), TANGENTS)


def random_rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def extremes(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return points.min(axis=0), points.max(axis=0)


@pytest.mark.parametrize("seed", range(5))
def test_primitive_box_is_the_shapes_extent(seed):
    """Against points of each shape's surface that reach its extremes: a box's corners,
    a capsule's end spheres at ±r on each axis, a cylinder's two rims (densely sampled)."""
    rng = np.random.default_rng(seed)
    R, c = random_rotation(rng), rng.normal(size=3)
    size = np.array([0.3, 0.5, 1.2])
    corners = c + (box_corners([(-size / 2, size / 2)])) @ R.T
    np.testing.assert_allclose(primitive_box(pb.GEOM_BOX, size, c, R), extremes(corners))

    length, radius = 0.8, 0.1
    ends = [c + s * length / 2 * R[:, 2] for s in (-1, 1)]
    caps = np.array(
        [e + s * radius * np.eye(3)[i] for e in ends for i in range(3) for s in (-1, 1)]
    )
    got = primitive_box(pb.GEOM_CAPSULE, (length, radius, 0.0), c, R)
    np.testing.assert_allclose(got, extremes(caps), atol=1e-12)

    angle = np.linspace(0, 2 * np.pi, 20000)
    circle = np.c_[np.cos(angle), np.sin(angle), np.zeros_like(angle)] * radius
    rims = np.concatenate([e + circle @ R.T for e in ends])
    lo, hi = primitive_box(pb.GEOM_CYLINDER, (length, radius, 0.0), c, R)
    rim_lo, rim_hi = extremes(rims)
    assert np.all(lo <= rim_lo + 1e-12) and np.all(hi >= rim_hi - 1e-12)
    np.testing.assert_allclose((lo, hi), (rim_lo, rim_hi), atol=1e-8)

    np.testing.assert_allclose(
        primitive_box(pb.GEOM_SPHERE, (0.2, 0.2, 0.2), c, R), (c - 0.2, c + 0.2)
    )
    assert primitive_box(pb.GEOM_MESH, (1.0, 1.0, 1.0), c, R) is None


def bounds(client, bodies):
    return extremes(box_corners(body_boxes(client, bodies)))


@pytest.mark.parametrize(
    "q, box",
    [
        ((0.0, 0.0), ((-0.1, -0.1, -0.1), (2.0, 0.1, 0.1))),  # stretched along +x
        ((math.pi / 2, 0.0), ((-0.1, -0.1, -0.1), (0.1, 0.1, 2.0))),  # straight up
    ],
)
def test_body_boxes_hold_the_visuals_of_a_robot_without_collision_shapes(client, q, box):
    """The planar arm has no collision shapes (PyBullet's AABB is a point per link): its
    cylinders' boxes reach the tip, 2 m from the base, in every configuration."""
    body = pb.loadURDF(str(resolve_robot("planar_2dof").urdf_path), physicsClientId=client)
    for j, angle in enumerate(q):
        pb.resetJointState(body, j, angle, physicsClientId=client)
    np.testing.assert_allclose(bounds(client, [body]), box, atol=1e-6)


def test_body_boxes_place_visuals_in_the_base_link_frame(client, tmp_path: Path):
    """PyBullet's base pose is the base's centre of mass (here shifted and turned in the
    link frame); a visual is placed in the link frame."""
    urdf = tmp_path / "offset.urdf"
    urdf.write_text(
        '<robot name="offset"><link name="base">'
        '<inertial><origin xyz="0.05 0 0.45" rpy="0 0 0.3"/><mass value="1"/>'
        '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>'
        '<visual><origin xyz="0 0 0.5"/><geometry><box size="0.4 0.2 0.2"/></geometry>'
        "</visual></link></robot>"
    )
    body = pb.loadURDF(str(urdf), [1.0, 2.0, 0.0], useFixedBase=True, physicsClientId=client)
    lo, hi = bounds(client, [body])  # the centre of mass's point box lies inside
    np.testing.assert_allclose((lo + hi) / 2, [1.0, 2.0, 0.5], atol=1e-6)
    np.testing.assert_allclose(hi - lo, [0.4, 0.2, 0.2], atol=1e-6)


def test_body_boxes_of_several_robots_are_each_robots(client):
    """Two iiwas 1 m apart: the boxes of both are those of each, the second's shifted."""
    urdf = str(resolve_robot("iiwa").urdf_path)
    a = pb.loadURDF(urdf, useFixedBase=True, physicsClientId=client)
    b = pb.loadURDF(urdf, [0.0, 1.0, 0.0], useFixedBase=True, physicsClientId=client)
    only_a, only_b = body_boxes(client, [a]), body_boxes(client, [b])
    np.testing.assert_allclose(
        box_corners(body_boxes(client, [a, b])), box_corners(only_a + only_b)
    )
    np.testing.assert_allclose(box_corners(only_b), box_corners(only_a) + [0, 1, 0], atol=1e-6)
    lo, hi = bounds(client, [a, b])
    assert lo[1] < -0.1 and hi[1] > 1.1 and hi[2] > 1.3  # both, base to flange


def test_frame_view_needs_a_gui(client):
    body = pb.loadURDF(str(resolve_robot("planar_2dof").urdf_path), physicsClientId=client)
    frame_view(client, [])  # nothing to aim at: only the panels, which DIRECT has none of
    with pytest.raises(ValueError, match="GUI"):
        frame_view(client, [body])
