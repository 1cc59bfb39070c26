"""Lines drawn over Blender's editors with the ``gpu`` module (no other imports, so the
drawing can be tested in a process that initialised ``gpu`` on its own)."""


def draw_vertical_lines(xs, bottom, top, color):
    """Vertical lines at ``xs`` from ``bottom`` to ``top`` in the current view coordinates
    (in a Dope Sheet's ``POST_VIEW`` handler, x is the frame).

    Parameters
    ----------
    xs : sequence of float
    bottom, top : float
    color : tuple of 4 float, RGBA in [0, 1]
    """
    import gpu
    from gpu_extras.batch import batch_for_shader

    coords = [(float(x), float(y)) for x in xs for y in (bottom, top)]
    shader = gpu.shader.from_builtin("UNIFORM_COLOR")
    batch = batch_for_shader(shader, "LINES", {"pos": coords})
    gpu.state.blend_set("ALPHA")
    shader.uniform_float("color", color)
    batch.draw(shader)
    gpu.state.blend_set("NONE")
