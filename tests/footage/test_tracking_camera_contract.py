"""The Blender-camera contract (core/tracking/camera.py) against Blender's own renders.

The calibration clip renders eight textured boxes on a blue world with a portrait resolution,
sensor fit AUTO and a lens shift; the tracker's model of the same boxes, projected through
``camera_from_blender``, must cover the same pixels.
"""

import numpy as np

from core.tracking.body_model import joint_frames_in_camera, ray_cast


def test_rendered_boxes_match_the_projected_model(calib_clip):
    fp = calib_clip
    cam = fp.camera
    assert cam.width < cam.height                  # portrait: AUTO fits the sensor to the height
    rot, org = joint_frames_in_camera(fp.skeleton, cam.world2camera, fp.root_translation,
                                      fp.local_rotations)
    v, u = np.mgrid[0:cam.height, 0:cam.width]
    hits = ray_cast(fp.body, cam, rot[0], org[0], np.stack([u.ravel(), v.ravel()], 1).astype(float))
    model = hits.parts.reshape(cam.height, cam.width)
    rgb = fp.rgb[0].astype(int)
    rendered = (rgb[..., 0] > 3) | (rgb[..., 1] > 3)      # not the pure blue world
    assert rendered.sum() > 1000
    iou = (rendered & (model >= 0)).sum() / (rendered | (model >= 0)).sum()
    assert iou > 0.95
    # Box by box: the rendered blob's centroid sits on the projected box's centroid.
    for p in range(fp.body.n_parts):
        mine = model == p
        assert mine.sum() > 100
        theirs = rendered & mine
        c_model = np.array([u[mine].mean(), v[mine].mean()])
        c_render = np.array([u[theirs].mean(), v[theirs].mean()])
        assert np.linalg.norm(c_model - c_render) < 0.25
        assert theirs.sum() / mine.sum() > 0.95
