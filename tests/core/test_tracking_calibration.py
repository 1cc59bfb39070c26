"""core.tracking.calibration: Pose2Sim Calib.toml and Qualisys .qca.txt, against an independent
re-implementation of Pose2Sim's converter (xml.etree + OpenCV) and OpenCV's projection."""

import shutil
import xml.etree.ElementTree as ET

import cv2
import numpy as np
import pytest

from core.tracking.calibration import (CalibrationError, fit_to_footage, qca_binning_factor,
                                       read_calibration)
from core.tracking.camera import (blender_from_camera, camera_from_blender,
                                  distortion_from_movie_clip, movie_clip_intrinsics)
from tests.data import ROOT

DEMO = ROOT / "sample_scenes/data/footage/pose2sim_single_person"
QCA = DEMO / "Calib.qca.txt"
RNG = np.random.default_rng(0)


def _pose2sim_qca(path, binning=1):
    """Pose2Sim's read_qca + calib_qca_fun, step by step as published (lists K, D, rvec, t)."""
    root = ET.parse(path).getroot()
    out = {}
    for cam in root.findall("cameras/camera"):
        fov, intr, tr = cam.find("fov_video"), cam.find("intrinsic"), cam.find("transform")
        g = lambda e, k: float(e.get(k))  # noqa: E731
        size = [(g(fov, "right") - g(fov, "left") + 1) / binning,
                (g(fov, "bottom") - g(fov, "top") + 1) / binning]
        d = np.array([g(intr, k) / 64 / binning for k in ("radialDistortion1", "radialDistortion2",
                                                          "tangentalDistortion1",
                                                          "tangentalDistortion2")])
        k = np.array([[g(intr, "focalLengthU") / 64 / binning, 0,
                       g(intr, "centerPointU") / 64 / binning - g(fov, "left")],
                      [0, g(intr, "focalLengthV") / 64 / binning,
                       g(intr, "centerPointV") / 64 / binning - g(fov, "top")], [0, 0, 1]])
        r = np.array([g(tr, f"r{i}{j}") for i in (1, 2, 3) for j in (1, 2, 3)]).reshape(3, 3).T
        t = np.array([g(tr, a) for a in "xyz"]) / 1000
        r, t = r.T, -r.T @ t                                     # world_to_camera_persp
        flip = np.array([[1, 0, 0], [0, -1, 0], [0, 0, -1.0]])   # rotate_cam(ang_x=pi)
        r, t = flip @ r, flip @ t
        out[cam.get("serial")] = (size, k, d, cv2.Rodrigues(r)[0].ravel(), t)
    return out


def test_qca_reads_as_pose2sim_converts_it():
    cameras = read_calibration(QCA)
    reference = _pose2sim_qca(QCA)
    assert [c.name for c in cameras] == ["cam01", "cam02", "cam03", "cam04"]
    for cam in cameras:
        size, k, d, rvec, t = reference[cam.name]
        assert (cam.width, cam.height) == tuple(size) == (1088, 1920)
        np.testing.assert_allclose(cam.matrix, k, atol=1e-9)
        np.testing.assert_allclose(cam.distortion, np.append(d, 0.0), atol=1e-15)
        np.testing.assert_allclose(cv2.Rodrigues(cam.world2camera[:3, :3])[0].ravel(), rvec,
                                   atol=1e-9)
        np.testing.assert_allclose(cam.world2camera[:3, 3], t, atol=1e-9)
        # The camera stands where the file puts it (mm -> m) and looks down at the platform.
        assert 1.5 < cam.camera2world[2, 3] < 2.5
        assert cam.camera2world[2, 2] < 0   # optical axis (camera z) points down


def test_projection_equals_opencv_through_the_calibration():
    """World points -> pixels: the core's camera equals cv2.projectPoints (0.1 px asked)."""
    for cam in read_calibration(QCA):
        # Points in front of the camera over the whole image, 2-6 m away.
        pixels = RNG.uniform([0, 0], [cam.width - 1, cam.height - 1], (500, 2))
        pin = cam.pinhole()
        local = pin.rays(pixels) * RNG.uniform(2, 6, (500, 1))
        world = (local - cam.world2camera[:3, 3]) @ cam.world2camera[:3, :3]
        ref, _ = cv2.projectPoints(world, cv2.Rodrigues(cam.world2camera[:3, :3])[0],
                                   cam.world2camera[:3, 3], cam.matrix, cam.distortion)
        ours = pin.project(pin.world_to_camera(world))
        assert np.abs(ours - ref[:, 0]).max() < 1e-6
        np.testing.assert_allclose(ours, pixels, atol=5e-3)   # rays: the lookup table


def _write_toml(path, cameras, extra=""):
    lines = []
    for cam in cameras:
        rvec = cv2.Rodrigues(cam.world2camera[:3, :3])[0].ravel()
        lines += [f"[{cam.name}]", f'name = "{cam.name}"',
                  f"size = [ {cam.width:.1f}, {cam.height:.1f}]",
                  "matrix = [ " + ", ".join("[ " + ", ".join(repr(float(v)) for v in row) + "]"
                                            for row in cam.matrix) + "]",
                  "distortions = [ " + ", ".join(repr(float(v)) for v in cam.distortion[:4]) + "]",
                  "rotation = [ " + ", ".join(repr(float(v)) for v in rvec) + "]",
                  "translation = [ " + ", ".join(repr(float(v)) for v in cam.world2camera[:3, 3])
                  + "]", "fisheye = false", ""]
    path.write_text("\n".join(lines) + "[metadata]\nadjusted = false\nerror = 0.0\n" + extra)


def test_toml_round_trip(tmp_path):
    cameras = read_calibration(QCA)
    path = tmp_path / "Calib.toml"
    _write_toml(path, cameras)
    again = read_calibration(path)
    assert [c.name for c in again] == [c.name for c in cameras]
    for a, b in zip(again, cameras):
        assert (a.width, a.height) == (b.width, b.height)
        np.testing.assert_allclose(a.matrix, b.matrix, atol=1e-12)
        np.testing.assert_allclose(a.distortion, b.distortion, atol=1e-18)
        np.testing.assert_allclose(a.world2camera, b.world2camera, atol=1e-12)
        assert a.line == path.read_text().splitlines().index(f"[{a.name}]") + 1


def test_binning_factor_from_config(tmp_path):
    assert qca_binning_factor(QCA)[0] == 1
    shutil.copy(QCA, tmp_path / "Calib.qca.txt")
    config = (DEMO / "Config.toml").read_text().replace("binning_factor = 1 ", "binning_factor = 2 ")
    (tmp_path / "Config.toml").write_text(config)
    assert qca_binning_factor(tmp_path / "Calib.qca.txt") == (2, str(tmp_path / "Config.toml"))
    binned = read_calibration(tmp_path / "Calib.qca.txt")
    reference = _pose2sim_qca(QCA, binning=2)
    for cam in binned:
        assert (cam.width, cam.height) == (544, 960)
        np.testing.assert_allclose(cam.matrix, reference[cam.name][1], atol=1e-9)
    (tmp_path / "Config.toml").write_text(config.replace("binning_factor = 2 ", "binning_factor = 0 "))
    with pytest.raises(CalibrationError, match=r"Config.toml, line 135: binning_factor"):
        read_calibration(tmp_path / "Calib.qca.txt")


def test_size_rule():
    cam = read_calibration(QCA)[0]
    same, note = fit_to_footage(cam, 1088, 1920)
    assert note == ""
    cropped, note = fit_to_footage(cam, 1080, 1920)
    assert "8 px cut at the right" in note and "principal point unchanged" in note
    assert (cropped.width, cropped.height) == (1080, 1920)
    pts = same.rays(RNG.uniform([0, 0], [1079, 1919], (100, 2))) * 3.0
    np.testing.assert_array_equal(cropped.project(pts), same.project(pts))
    with pytest.raises(CalibrationError, match="calibrated for 1088x1920 px but its footage is "
                                               "540x960"):
        fit_to_footage(cam, 540, 960)


def test_blender_camera_and_clip_round_trip():
    """Blender camera settings + the clip's tracking camera give back the calibrated camera."""
    for cam in read_calibration(QCA):
        pin, _ = fit_to_footage(cam, 1080, 1920)
        b = blender_from_camera(pin, sensor_width=6.03)
        back = camera_from_blender(b["lens"], b["sensor_width"], b["sensor_height"],
                                   b["sensor_fit"], b["shift_x"], b["shift_y"], *b["resolution"],
                                   b["matrix_world"], b["pixel_aspect_x"], b["pixel_aspect_y"])
        for name in ("fx", "fy", "cx", "cy"):
            assert abs(getattr(back, name) - getattr(pin, name)) < 1e-9
        np.testing.assert_allclose(back.world2camera, pin.world2camera, atol=1e-12)
        clip = movie_clip_intrinsics(pin)
        coefficients = dict(zip(("brown_k1", "brown_k2", "brown_k3", "brown_k4", "brown_p1",
                                 "brown_p2"), clip["brown"]))
        d = distortion_from_movie_clip(back, clip["focal_length_pixels"],
                                       clip["principal_point_pixels"], clip["pixel_aspect"],
                                       "BROWN", coefficients)
        np.testing.assert_allclose(d, cam.distortion, atol=1e-18)
        with pytest.raises(ValueError, match="does not match the camera"):
            distortion_from_movie_clip(back, clip["focal_length_pixels"] * 1.01,
                                       clip["principal_point_pixels"], clip["pixel_aspect"],
                                       "BROWN", coefficients)
    assert distortion_from_movie_clip(back, 1.0, (0, 0), 1.0, "POLYNOMIAL",
                                      {"k1": 0.0, "k2": 0.0, "k3": 0.0}) is None
    with pytest.raises(ValueError, match="Division is not supported"):
        distortion_from_movie_clip(back, 1.0, (0, 0), 1.0, "DIVISION",
                                   {"division_k1": 0.1, "division_k2": 0.0})


TOML_GOOD = """[cam01]
name = "cam01"
size = [ 1088.0, 1920.0]
matrix = [ [ 1681.2, 0.0, 533.0], [ 0.0, 1681.0, 948.1], [ 0.0, 0.0, 1.0]]
distortions = [ -0.0007, 0.002, 0.0, 0.0]
rotation = [ 1.68, 1.04, -0.41]
translation = [ 0.32, 0.95, 2.89]
fisheye = false
"""


@pytest.mark.parametrize("text, message", [
    (TOML_GOOD.replace("size = [", "size = ["), None),
    (TOML_GOOD.replace("size = [ 1088.0, 1920.0]", "size = [ 1088.0 1920.0]"), r"line 3: not a valid TOML"),
    (TOML_GOOD.replace("distortions = [ -0.0007, 0.002, 0.0, 0.0]\n", ""), r"line 1: camera table \[cam01\] has no 'distortions'"),
    (TOML_GOOD.replace("[ 0.0, 0.0, 1.0]]", "]"), r"line 4: 'matrix' must have shape \(3, 3\)"),
    (TOML_GOOD.replace("0.32, 0.95", "nan, 0.95"), r"line 7: 'translation' holds non-finite"),
    (TOML_GOOD.replace("fisheye = false", "fisheye = true"), r"line 8: camera \[cam01\] is a fisheye"),
    (TOML_GOOD.replace("0.0, 0.0]\n", "0.0]\n"), r"line 5: Expected 4 or 5 distortion"),
    (TOML_GOOD.replace("1681.2, 0.0, 533.0", "-1681.2, 0.0, 533.0"), r"line 1: camera 'cam01': focal lengths"),
    (TOML_GOOD.replace("-0.0007, 0.002", "-0.9, 0.0"), r"line 1: camera 'cam01': Lens distortion"),
    ("[metadata]\nerror = 0.0\n", r"no camera table"),
])
def test_toml_refusals_name_file_and_line(tmp_path, text, message):
    path = tmp_path / "Calib.toml"
    path.write_text(text)
    if message is None:
        assert len(read_calibration(path)) == 1
        return
    with pytest.raises(CalibrationError, match=message) as info:
        read_calibration(path)
    assert str(path) in str(info.value)


def _qca_text():
    return QCA.read_text()


@pytest.mark.parametrize("edit, message", [
    (lambda s: s.replace("<cameras>", "<cameras", 1), r"line [45]: not a valid XML"),
    (lambda s: s.replace('focalLengthU="107599.671875" ', "", 1), r"line 11: <intrinsic> has no focalLengthU"),
    (lambda s: s.replace('r11="0.5536380477336265"', 'r11="abc"', 1), r"line 10: <transform r11=\"abc\"> is not a number"),
    (lambda s: s.replace('r11="0.5536380477336265"', 'r11="0.9"', 1), r"line 10: camera 'cam01': r11…r33 is not a rotation"),
    (lambda s: s.replace('viewrotation="0"', 'viewrotation="90"', 1), r"line 5: camera 'cam01' has viewrotation=\"90\""),
    (lambda s: s.replace('x="1460.2323709212087"', 'x="inf"', 1), r"line 10: <transform x=\"inf\"> is not finite"),
    (lambda s: s.replace('model="none"', 'model="Miqus M3"'), r"no video camera"),
    (lambda s: s.replace("<fov_video ", "<fov_other ", 1), r"line 5: <camera> has no <fov_video>"),
])
def test_qca_refusals_name_file_and_line(tmp_path, edit, message):
    path = tmp_path / "Calib.qca.txt"
    path.write_text(edit(_qca_text()))
    with pytest.raises(CalibrationError, match=message) as info:
        read_calibration(path)
    assert str(path) in str(info.value)


def test_missing_file_is_reported(tmp_path):
    with pytest.raises(CalibrationError, match="cannot read the file"):
        read_calibration(tmp_path / "nothing.toml")
