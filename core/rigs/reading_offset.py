"""The reading offset of a rig read through the CMU template (NumPy only; ``docs/gait.md``,
*Stop 47, the rig's reading offset*).

A mapped rig is read into the gait model's joint space through the CMU template's rest
directions and axes (:mod:`.gait_space`; the template is subject 08's ASF).
A walk keyed on the rig was made on some other skeleton -- the test rigs carry subject 35's
walk, retargeted bone direction by bone direction -- whose rest convention differs from the
template's: read through the template, every frame of it carries a constant difference in the
angle channels, ``r`` (on the test rigs: 16° of the right upper arm's twist, 14° at the
clavicles, 6.6° at the right foot; Rigify's upper neck 23°). Nothing on the rig tells ``r``: a rig at
rest reads zero whatever walk is keyed on it. So the gait sees it as part of the walker's
posture offset, with a prior of its own: ``r ~ N(0, diag(sd²))``, the spread of the reading
offsets of the CMU subjects that have their own ASF (:data:`READING_OFFSET_SD`, measured by
``benchmarks/studies/reading_offset.py``). Unlike the walker's own posture, nothing about a
window's length makes it smaller: a short window tightens the walker's part only
(``core.gait.em.short_window_context``).
"""

import numpy as np

__all__ = ["READING_OFFSET_SD", "reading_offset_variance"]

#: Degrees: per model angle channel, the root mean square over 11 CMU subjects with their own
#: ASF (05, 06, 08, 35, 49, 64, 74, 79, 120, 124, 126; one clip each) of the median difference
#: between the clip read from a rig (two neck bones, as Rigify's and the metarig's) through the
#: template and its own DOFs (``benchmarks/studies/reading_offset.py --table``). Channels the
#: study's rig does not observe (fingers, thumbs) are not listed: no reading offset for them.
READING_OFFSET_SD = {
    "lfemur.rx": 0.00, "lfemur.ry": 0.00, "lfemur.rz": 0.00, "ltibia.rx": 0.00,
    "lfoot.rx": 4.66, "lfoot.rz": 0.08, "ltoes.rx": 4.66,
    "rfemur.rx": 0.00, "rfemur.ry": 0.00, "rfemur.rz": 0.00, "rtibia.rx": 0.00,
    "rfoot.rx": 5.65, "rfoot.rz": 0.04, "rtoes.rx": 5.65,
    "lowerback.rx": 3.81, "lowerback.ry": 0.18, "lowerback.rz": 1.21,
    "upperback.rx": 4.31, "upperback.ry": 0.28, "upperback.rz": 2.06,
    "thorax.rx": 1.77, "thorax.ry": 0.37, "thorax.rz": 0.61,
    "lowerneck.rx": 3.60, "lowerneck.ry": 0.55, "lowerneck.rz": 2.09,
    "upperneck.rx": 7.14, "upperneck.ry": 1.22, "upperneck.rz": 3.15,
    "head.rx": 6.59, "head.ry": 0.29, "head.rz": 2.72,
    "lclavicle.ry": 7.94, "lclavicle.rz": 5.87,
    "lhumerus.rx": 5.00, "lhumerus.ry": 6.81, "lhumerus.rz": 7.75,
    "lradius.rx": 0.00, "lwrist.ry": 0.00, "lhand.rx": 0.00, "lhand.rz": 0.00,
    "rclavicle.ry": 7.80, "rclavicle.rz": 8.17,
    "rhumerus.rx": 4.18, "rhumerus.ry": 7.08, "rhumerus.rz": 8.40,
    "rradius.rx": 0.00, "rwrist.ry": 0.00, "rhand.rx": 0.00, "rhand.rz": 0.00,
}


def reading_offset_variance(model):
    """Variance of the template reading's offset per model channel.

    Parameters
    ----------
    model : GaitModel

    Returns
    -------
    ndarray, shape (D,)
        Scaled units² (``model.channel_scale``), all model channels; zero for channels
        without an entry in :data:`READING_OFFSET_SD` (root features among them).
    """
    var = np.zeros(model.n_channels)
    for k, name in enumerate(model.channel_names):
        if name in READING_OFFSET_SD:
            var[k] = (np.radians(READING_OFFSET_SD[name]) / model.channel_scale[k]) ** 2
    return var
