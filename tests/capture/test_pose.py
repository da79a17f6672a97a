"""Head pose from the generic face, and feature points with the pose removed."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.curves import CURVE_NAMES, curve_points
from facepuppet.capture.pose import (
    FRONTAL_ROTATION,
    GENERIC_FACE,
    STABLE_FEATURES,
    FailedPose,
    HeadPose,
    default_camera,
    estimate_pose,
    generic_curves,
    generic_points,
    points_in_head,
    pose_points_from_curves,
)

SIZE = (640, 480)


def rotation(yaw=0.0, pitch=0.0, roll=0.0):
    """Head-to-camera rotation of a head turned by yaw/pitch/roll (degrees) about its own y, x, z axes."""
    y, p, r = np.radians([yaw, pitch, roll])
    Ry = cv2.Rodrigues(np.array([0.0, y, 0.0]))[0]
    Rx = cv2.Rodrigues(np.array([p, 0.0, 0.0]))[0]
    Rz = cv2.Rodrigues(np.array([0.0, 0.0, r]))[0]
    return FRONTAL_ROTATION @ Ry @ Rx @ Rz


def project(points, R, t, size=SIZE):
    return HeadPose(R, t, default_camera(size)).project(points)


def angle_between(R1, R2):
    return np.degrees(np.arccos(np.clip((np.trace(R1.T @ R2) - 1) / 2, -1, 1)))


def test_frontal_rotation_is_right_handed_and_generic_face_is_symmetric():
    assert np.isclose(np.linalg.det(FRONTAL_ROTATION), 1.0)
    for name, (x, y, z) in GENERIC_FACE.items():
        if "left" in name:
            assert np.allclose(GENERIC_FACE[name.replace("left", "right")], (-x, y, z))
    # the performer's left eye appears on the image's right in a frontal view
    uv = project(np.array([GENERIC_FACE["eye_left_outer"], GENERIC_FACE["eye_right_outer"]]),
                 FRONTAL_ROTATION, np.array([0, 0, 50.0]))
    assert uv[0, 0] > SIZE[0] / 2 > uv[1, 0]


@pytest.mark.parametrize("yaw,pitch,roll", [(0, 0, 0), (25, -10, 8), (-30, 15, -12), (10, 20, 170)])
def test_roll_is_the_angles_roll_to_the_last_bit(yaw, pitch, roll):
    pose = HeadPose(rotation(yaw, pitch, roll), np.array([0.0, 0.0, 50.0]), default_camera(SIZE))
    assert pose.roll == pose.angles()[2]
    assert np.isclose(pose.roll, np.radians(roll))


@pytest.mark.parametrize("yaw,pitch,roll", [(0, 0, 0), (25, -10, 8), (-30, 15, -12), (10, 20, 30)])
def test_pose_recovers_a_known_rotation_from_noisy_projections(yaw, pitch, roll, rng):
    R = rotation(yaw, pitch, roll)
    t = np.array([3.0, -2.0, 55.0])
    names = STABLE_FEATURES + ("nose_tip", "mouth_left", "mouth_right")
    xyz = np.array([GENERIC_FACE[n] for n in names])
    uv = project(xyz, R, t) + rng.normal(0, 0.5, (len(names), 2))
    pose = estimate_pose(dict(zip(names, uv, strict=True)), SIZE)
    assert pose
    assert angle_between(pose.rotation, R) < 2.0
    assert np.allclose(pose.translation, t, atol=1.5)
    assert np.allclose(pose.angles(), np.radians([yaw, pitch, roll]), atol=np.radians(2.5))
    assert pose.reprojection_error < 1.5


def test_pose_from_stable_features_only_and_previous_guess(rng):
    R = rotation(20, 5, -5)
    t = np.array([0.0, 1.0, 60.0])
    uv = project(np.array([GENERIC_FACE[n] for n in STABLE_FEATURES]), R, t) + rng.normal(0, 0.3, (7, 2))
    first = estimate_pose(uv, SIZE)
    assert first and angle_between(first.rotation, R) < 3.0
    R2 = rotation(23, 6, -4)
    uv2 = project(np.array([GENERIC_FACE[n] for n in STABLE_FEATURES]), R2, t)
    second = estimate_pose(uv2, SIZE, previous=first)
    assert second and angle_between(second.rotation, R2) < 0.5


@pytest.mark.parametrize("roll", [0.0, 12.0, -20.0])
def test_upright_pose_keeps_roll_and_fits_translation(roll):
    """out_of_plane=False: yaw and pitch held at zero, roll and position solved; exact for an upright head
    anywhere in the image (the translation's linear least squares has an exact solution)."""
    xyz = np.array([GENERIC_FACE[n] for n in STABLE_FEATURES])
    R = rotation(roll=roll)
    for t in (np.array([0.0, 0.0, 50.0]), np.array([9.0, -6.0, 45.0])):
        pose = estimate_pose(project(xyz, R, t), SIZE, out_of_plane=False)
        assert pose and np.allclose(pose.rotation, R, atol=1e-6) and np.allclose(pose.translation, t, atol=1e-4)
        assert np.allclose(pose.angles(), np.radians([0.0, 0.0, roll]), atol=1e-6)
        # from the last frame's pose (the tracker's path), to a head rolled 5 degrees further and moved
        R2, t2 = rotation(roll=roll + 5.0), t + np.array([1.0, -0.5, 2.0])
        again = estimate_pose(project(xyz, R2, t2), SIZE, out_of_plane=False, previous=pose)
        assert again and np.allclose(again.rotation, R2, atol=1e-6) and np.allclose(again.translation, t2, atol=1e-4)


def test_upright_pose_does_not_turn_a_layout_placed_off_centre_towards_the_camera():
    """Landmarks placed by an in-plane similarity (the frontal layout moved across the image, as the colour
    tracker places them) carry no turn: a free solve turns the head towards the camera by about the angle of
    the ray to it, against the ray's sign (a head on the image's right is turned to its right, negative yaw;
    one above the centre, negative ray y, is turned down, positive pitch), the upright solve keeps it facing
    along the optical axis. On a clip whose head turns as it moves across the frame, a free solve of such
    points therefore runs against the real turn: no convention is wrong."""
    xyz = np.array([GENERIC_FACE[n] for n in STABLE_FEATURES])
    layout = project(xyz, FRONTAL_ROTATION, np.array([0.0, 0.0, 50.0]))
    shift = np.array([60.0, -40.0])                         # the same picture, moved right and up
    free = estimate_pose(layout + shift, SIZE)
    upright = estimate_pose(layout + shift, SIZE, out_of_plane=False)
    yaw_free, pitch_free, _ = np.degrees(free.angles())
    ray_x, ray_y = np.degrees(np.arctan(shift / default_camera(SIZE)[0, 0]))
    assert -1.3 * ray_x < yaw_free < -0.5 * ray_x and -1.3 * ray_y > pitch_free > -0.5 * ray_y
    yaw, pitch, roll = np.degrees(upright.angles())
    assert yaw == pytest.approx(0.0, abs=1e-9) and pitch == pytest.approx(0.0, abs=1e-9) and abs(roll) < 1.0
    assert upright.reprojection_error < 1.0


def test_upright_pose_of_another_faces_layout_is_in_front_of_the_camera():
    """The colour tracker's stable points are its profile's layout placed by a similarity: another face than the
    generic one. Their depths barely tell the first upright solve's (c, s, t) from (−c, −s, −t), a head turned
    upside down behind the camera (the first solve took that in 92 of these 200 layouts and the pose failed);
    every one is solved in front of the camera, upright as it was placed, and fits."""
    xyz = np.array([GENERIC_FACE[n] for n in STABLE_FEATURES])
    rng = np.random.default_rng(0)
    for _ in range(200):
        stretch = rng.uniform(0.8, 1.25, 2)                 # wider or narrower, longer or shorter than the generic
        a, scale, at = rng.uniform(-0.3, 0.3), rng.uniform(2.0, 8.0), rng.uniform([200, 150], [440, 330])
        turn = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        placed = [(xyz[:, :2] * s * [1.0, -1.0]) @ turn.T * scale + at for s in (stretch, np.ones(2))]
        pose = estimate_pose(placed[0], SIZE, out_of_plane=False)
        assert pose and pose.translation[2] > 0, (stretch, a)
        generic = estimate_pose(placed[1], SIZE, out_of_plane=False)     # the same placement, unstretched
        assert abs(np.degrees(pose.angles()[2] - generic.angles()[2])) < 3.0
        assert pose.reprojection_error < 0.1 * scale * np.ptp(xyz[:, 0])


def test_up_vector_in_the_image_follows_roll():
    t = np.array([0.0, 0.0, 50.0])
    assert np.allclose(HeadPose(rotation(), t, default_camera(SIZE)).up_vector_image(), [0, -1], atol=1e-9)
    # roll the head by +30 degrees about its forward axis: up tilts towards the performer's right (image left)
    up = HeadPose(rotation(roll=30), t, default_camera(SIZE)).up_vector_image()
    assert np.allclose(up, [-np.sin(np.radians(30)), -np.cos(np.radians(30))], atol=1e-6)


def test_failures_are_falsy_with_a_reason():
    few = estimate_pose({"eye_left_inner": (1, 2), "eye_left_outer": (5, 2), "nose_base": (3, 8)}, SIZE)
    assert isinstance(few, FailedPose) and not few and "at least 4" in few.reason
    nan = estimate_pose(np.full((7, 2), np.nan), SIZE)
    assert not nan
    scrambled = estimate_pose(np.random.default_rng(0).uniform(0, 400, (7, 2)), SIZE)
    assert not scrambled and scrambled.reason
    with pytest.raises(ValueError, match="unknown landmark"):
        estimate_pose({"ear": (0, 0)}, SIZE)


def test_points_in_head_agree_for_frontal_and_rotated_views(rng):
    # an expression: the generic curves with the mouth opened and a brow raised, moved within the face plane
    curves3d = generic_curves()
    idx = {c: i for i, c in enumerate(CURVE_NAMES)}
    curves3d[idx["lip_lower_outer"], 1:3, 1] -= 0.8
    curves3d[idx["lip_lower_inner"], 1:3, 1] -= 0.8
    curves3d[idx["brow_left"], :, 1] += 0.4
    expected = curve_points(curves3d)  # the expression's feature points in head coordinates
    # the edit moved points within planes parallel to the face: depths stay the generic face's
    assert np.allclose(expected[:, 2], generic_points()[:, 2])
    assert not np.allclose(expected, generic_points())
    results = []
    for R, t in [(rotation(), np.array([0.0, 0.0, 50.0])), (rotation(30, -15, 10), np.array([4.0, -3.0, 65.0]))]:
        names = STABLE_FEATURES
        uv_stable = project(np.array([GENERIC_FACE[n] for n in names]), R, t)
        pose = estimate_pose(uv_stable, SIZE)
        assert pose
        image_curves = project(curves3d.reshape(-1, 3), R, t).reshape(-1, 4, 2)
        pts = points_in_head(image_curves, pose, SIZE)
        assert pts.shape == (48, 3)
        results.append(pts)
        assert np.allclose(pts, expected, atol=0.05)
    assert np.allclose(results[0], results[1], atol=0.05)


def test_points_in_head_of_a_failed_pose_are_nan():
    pts = points_in_head(np.zeros((12, 4, 2)), FailedPose("lost"), SIZE)
    assert pts.shape == (48, 3) and np.isnan(pts).all()


def test_pose_points_from_curves_reads_curve_ends():
    curves = np.arange(12 * 4 * 2, dtype=float).reshape(12, 4, 2)
    pts = pose_points_from_curves(curves)
    assert set(pts) == set(STABLE_FEATURES)
    assert np.allclose(pts["eye_left_outer"], curves[CURVE_NAMES.index("eye_left_upper"), 3])
    assert np.allclose(pts["ala_right"], curves[CURVE_NAMES.index("nostril_right"), 0])


def test_gauss_newton_refinement_agrees_with_solvepnp():
    from facepuppet.capture.generic_face import generic_landmarks
    from facepuppet.capture.pose import STABLE_FEATURES, camera_matrix, refine_pose

    xyz = np.array(generic_landmarks(STABLE_FEATURES))
    K = np.array(camera_matrix(640.0, 480.0, None))
    R = cv2.Rodrigues(np.array([0.15, -0.3, 0.1]))[0] @ np.diag([1.0, -1.0, -1.0])
    t = np.array([2.0, -1.0, 45.0])
    proj = (xyz @ R.T + t) @ K.T
    uv = proj[:, :2] / proj[:, 2:] + np.random.default_rng(0).normal(0.0, 0.7, (len(xyz), 2))
    R0 = cv2.Rodrigues(np.array([0.05, 0.04, -0.03]))[0] @ R
    Rg, tg, ok = refine_pose(xyz, uv, K, R0, t + 0.5)
    assert ok
    _, rvec, tvec = cv2.solvePnP(xyz, uv, K, None, cv2.Rodrigues(R0)[0], (t + 0.5).reshape(3, 1),
                                 useExtrinsicGuess=True, flags=cv2.SOLVEPNP_ITERATIVE)
    assert np.allclose(Rg, cv2.Rodrigues(rvec)[0], atol=1e-5)
    assert np.allclose(tg, tvec.ravel(), atol=1e-4)
