"""The one way operators turn a bridge call into reports (operators stay ~20-line adapters)."""


def report_outcome(operator, errors, action):
    """Run ``action()`` and report its outcome on ``operator``.

    Parameters
    ----------
    operator : bpy.types.Operator
    errors : type or tuple of type
        The domain exceptions that mean "cannot run": reported as ERROR, nothing else is caught.
    action : callable
        Returns the INFO line to report.

    Returns
    -------
    set
        ``{'FINISHED'}`` or ``{'CANCELLED'}``.
    """
    try:
        summary = action()
    except errors as exc:
        operator.report({"ERROR"}, str(exc))
        return {"CANCELLED"}
    operator.report({"INFO"}, summary)
    return {"FINISHED"}


def one_line(docstring):
    """A class docstring as a tooltip: one line, the source's line breaks and indentation
    folded into single spaces (Blender shows ``__doc__`` verbatim otherwise). Use as
    ``bl_description = one_line(__doc__)`` in an operator's class body."""
    return " ".join((docstring or "").split())


def show_progress(context, area, fraction, text):
    """A long run's progress: the progress bar at ``fraction`` (0–1), ``text`` in the status
    bar and in ``area``'s header. Returns ``area``, or None once that area has been closed."""
    context.window_manager.progress_update(int(100 * fraction))
    if context.workspace is not None:
        context.workspace.status_text_set(text)
    return _set_header(area, text)


def clear_progress_text(context, area):
    """Status bar and ``area``'s header back to Blender's own text."""
    if context.workspace is not None:
        context.workspace.status_text_set(None)
    _set_header(area, None)


def _set_header(area, text):
    if area is None:
        return None
    try:
        area.header_text_set(text)
    except ReferenceError:                       # the area was closed meanwhile
        return None
    return area
