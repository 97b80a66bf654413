r"""Frame the robots in PyBullet's GUI, without ROS: the camera sees every body, no panels.

PyBullet's debug-visualizer camera looks at a target t from a distance d along the
direction of yaw ψ and pitch θ [deg] (the convention of ``computeViewMatrixFromYawPitchRoll``
with z up):

    f = (−sin ψ cos θ, cos ψ cos θ, sin θ),   r = f × z / |f × z|,   u = r × f,
    eye = t − d f.

A point p (relative to t) is in the picture when |p·r| ≤ tan α_x (d + p·f) and
|p·u| ≤ tan α_y (d + p·f), with α_x, α_y the half fields of view of the GUI's projection
(:func:`half_fov_tangents`). :func:`fit_camera` finds the closest eye that has every given
point within the fraction ``fill`` of both half fields, the picture centred.

The points are the corners of a box per link of every body: PyBullet's AABB (the collision
shapes) and the box around each primitive visual shape (a link without collision shapes,
as the planar arm's, has only a point for an AABB). Their bounding box is the union of the
links' boxes; framing the corners of each rather than of the union keeps robots standing
apart from leaving the empty corners of their union in the picture.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
import pybullet as pb

#: PyBullet's own default camera direction [deg], kept so the view looks familiar.
DEFAULT_YAW = 50.0
DEFAULT_PITCH = -35.0
#: The outermost points reach this fraction of the half fields of view.
DEFAULT_FILL = 0.85
#: The farthest point is at most this many times farther from the eye than the nearest.
DEFAULT_DEPTH_RATIO = 4.0
#: The closest the camera's target comes to its eye [m] (a box of zero size).
MIN_DISTANCE = 0.1
#: The GUI's panels: the explorer/parameter/log widgets and the synthetic-camera previews.
PANELS = (
    pb.COV_ENABLE_GUI,
    pb.COV_ENABLE_RGB_BUFFER_PREVIEW,
    pb.COV_ENABLE_DEPTH_BUFFER_PREVIEW,
    pb.COV_ENABLE_SEGMENTATION_MARK_PREVIEW,
)

Box = tuple[np.ndarray, np.ndarray]  # (lower corner, upper corner) [m], world frame


def camera_axes(yaw: float, pitch: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(forward f, right r, up u) of the camera at yaw ψ and pitch θ [deg], z up."""
    psi, theta = np.radians(yaw), np.radians(pitch)
    if abs(np.cos(theta)) < 1e-6:
        raise ValueError("pitch must not be ±90 deg (the camera's right is undefined)")
    forward = np.array([-np.sin(psi) * np.cos(theta), np.cos(psi) * np.cos(theta), np.sin(theta)])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return forward, right, np.cross(right, forward)


def half_fov_tangents(projection: Sequence[float]) -> tuple[float, float]:
    """(tan α_x, tan α_y) of a perspective projection matrix given as PyBullet's 16 numbers
    (column-major): P₀₀ = 1 / tan α_x, P₁₁ = 1 / tan α_y."""
    p = np.asarray(projection, dtype=float)
    if p.shape != (16,) or not (p[0] > 0 and p[5] > 0):
        raise ValueError(f"not a perspective projection matrix: {p.tolist()}")
    return 1.0 / p[0], 1.0 / p[5]


def primitive_box(
    geometry: int, dimensions: Sequence[float], position: Sequence[float], rotation: np.ndarray
) -> Box | None:
    """World box of a primitive shape (PyBullet's ``GEOM_*`` and visual dimensions: box
    full sizes; sphere radius; cylinder and capsule length, radius along the local z axis)
    centred at ``position`` with orientation ``rotation``; None for meshes and planes."""
    d = np.asarray(dimensions, dtype=float)
    R = np.asarray(rotation, dtype=float)
    if geometry == pb.GEOM_BOX:
        half = np.abs(R) @ (d / 2.0)
    elif geometry == pb.GEOM_SPHERE:
        half = np.full(3, d[0])
    elif geometry in (pb.GEOM_CYLINDER, pb.GEOM_CAPSULE):
        axis = np.abs(R[:, 2])
        length, radius = d[0], d[1]
        # a disc of radius ρ with normal a reaches ρ √(1 − a_i²) along axis i
        rim = radius if geometry == pb.GEOM_CAPSULE else radius * np.sqrt(1.0 - axis**2)
        half = axis * length / 2.0 + rim
    else:
        return None
    centre = np.asarray(position, dtype=float)
    return centre - half, centre + half


def box_corners(boxes: Iterable[Box]) -> np.ndarray:
    """The eight corners of every box, one per row [m]."""
    signs = np.array([[sx, sy, sz] for sx in (0, 1) for sy in (0, 1) for sz in (0, 1)])
    rows = [np.asarray(lo, float) + signs * (np.asarray(hi, float) - lo) for lo, hi in boxes]
    return np.concatenate(rows) if rows else np.empty((0, 3))


def fit_camera(
    points: np.ndarray,
    tangents: tuple[float, float],
    yaw: float = DEFAULT_YAW,
    pitch: float = DEFAULT_PITCH,
    fill: float = DEFAULT_FILL,
    depth_ratio: float = DEFAULT_DEPTH_RATIO,
) -> tuple[float, np.ndarray]:
    r"""(distance d [m], target t) of the camera looking from yaw, pitch [deg] that comes
    closest to the ``points`` (rows, world frame [m]) with their picture centred and within
    ``fill`` of the half fields of view.

    In the camera's axes a point p = p_r r + p_u u + p_f f lies at depth D = p_f − e_f
    ahead of the eye e and is drawn at (p_u − e_u) / (D tan α_y) of the half height
    (across likewise, with r and α_x). The condition |p_u − e_u| ≤ k D, k = fill tan α_y,
    is linear in e: some e_u meets it for every point while

        e_f ≤ (min(p_u + k p_f) − max(p_u − k p_f)) / (2k).

    So that a scene deep along the view (an arm pointing at the camera) is not seen from
    right in front of its near end, the eye also keeps max D ≤ ρ min D, ρ = ``depth_ratio``
    (the near end drawn at most ρ times the scale of the far end):

        e_f ≤ (ρ min p_f − max p_f) / (ρ − 1).

    The eye comes as far forward as these three allow; then in each direction it takes the
    e_u that minimises the picture's half extent s (in units of D, |p_u − e_u| ≤ s D):

        s* = max over pairs (i, j) of (p_u,j − p_u,i) / (D_i + D_j),
        e_u = max_j (p_u,j − s* D_j),

    where the highest and the lowest point are drawn at ±s* / tan α_y: centred, and at
    ±fill in the direction that holds the eye back (unless the depth ratio does). The
    target is the point ahead of the eye level with the centre c of the points' bounding
    box (the GUI's mouse turns the view about it), t = e + d f with d = (c − e)·f; points
    too close together for that put the eye :data:`MIN_DISTANCE` back from t.

    Given the corners of each link's box rather than of their union, the empty space
    between robots standing apart does not push the camera back.
    """
    if not 0.0 < fill <= 1.0:
        raise ValueError(f"fill must be in (0, 1], got {fill}")
    if not depth_ratio > 1.0:
        raise ValueError(f"depth_ratio must be > 1, got {depth_ratio}")
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(points) == 0:
        raise ValueError("no points to frame")
    forward, right, up = camera_axes(yaw, pitch)
    depth = points @ forward
    eye_f = (depth_ratio * depth.min() - depth.max()) / (depth_ratio - 1.0)
    axes = ((right, fill * tangents[0]), (up, fill * tangents[1]))
    for axis, k in axes:
        across = points @ axis
        eye_f = min(eye_f, (np.min(across + k * depth) - np.max(across - k * depth)) / (2 * k))
    eye = eye_f * forward
    ahead = np.maximum(depth - eye_f, 0.0)  # ≥ 0 by the bounds above, up to rounding
    for axis, _ in axes:
        across = points @ axis
        pairs = across[None, :] - across[:, None]  # p_j − p_i
        sums = ahead[:, None] + ahead[None, :]  # D_i + D_j
        half = np.max(np.divide(pairs, sums, out=np.zeros_like(pairs), where=sums > 0))
        eye = eye + np.max(across - half * ahead) * axis
    centre = (points.min(axis=0) + points.max(axis=0)) / 2.0
    reach = float((centre - eye) @ forward)
    return max(reach, MIN_DISTANCE), eye + reach * forward


def body_boxes(client: int, bodies: Sequence[int]) -> list[Box]:
    """Boxes of every link (base included) of the bodies: PyBullet's AABB and the box of
    each primitive visual shape."""
    boxes: list[Box] = []
    for body in bodies:
        links = range(-1, pb.getNumJoints(body, physicsClientId=client))
        boxes += [pb.getAABB(body, link, physicsClientId=client) for link in links]
        for shape in pb.getVisualShapeData(body, physicsClientId=client):
            link, geometry, dimensions = shape[1], shape[2], shape[3]
            position, orientation = pb.multiplyTransforms(
                *_link_frame(client, body, link), shape[5], shape[6]
            )
            rotation = np.reshape(pb.getMatrixFromQuaternion(orientation), (3, 3))
            box = primitive_box(geometry, dimensions, position, rotation)
            if box is not None:
                boxes.append(box)
    return boxes


def _link_frame(client: int, body: int, link: int) -> tuple[Sequence[float], Sequence[float]]:
    """World pose of a link's URDF frame, which visual shapes are placed in (PyBullet's
    base pose is the base's centre of mass: its inertial frame is taken off)."""
    if link >= 0:
        state = pb.getLinkState(body, link, computeForwardKinematics=True, physicsClientId=client)
        return state[4], state[5]
    com = pb.getBasePositionAndOrientation(body, physicsClientId=client)
    inertial = pb.getDynamicsInfo(body, -1, physicsClientId=client)[3:5]
    return pb.multiplyTransforms(*com, *pb.invertTransform(*inertial))


def frame_view(
    client: int,
    bodies: Sequence[int],
    yaw: float = DEFAULT_YAW,
    pitch: float = DEFAULT_PITCH,
    fill: float = DEFAULT_FILL,
) -> None:
    """Hide the GUI's panels and aim its camera at all the bodies, as they stand now, seen
    from yaw and pitch [deg] (no bodies: only the panels go). ``client``: a ``pb.GUI``
    connection (ValueError otherwise)."""
    for panel in PANELS:
        pb.configureDebugVisualizer(panel, 0, physicsClientId=client)
    points = box_corners(body_boxes(client, bodies))
    if len(points) == 0:
        return
    projection = pb.getDebugVisualizerCamera(physicsClientId=client)[3]
    if not any(projection):
        raise ValueError(f"PyBullet client {client} has no GUI camera (not a pb.GUI client)")
    distance, target = fit_camera(points, half_fov_tangents(projection), yaw, pitch, fill)
    pb.resetDebugVisualizerCamera(distance, yaw, pitch, target.tolist(), physicsClientId=client)
