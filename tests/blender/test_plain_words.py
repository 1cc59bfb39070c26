"""An animator's words (issue 14): every operator, panel, menu and property the extension
registers has a one-line description (tooltips without the docstrings' line breaks and
indentation), and nothing a user reads in the UI -- labels, item names, panel titles, marker
names -- uses the papers' terms (they stay in tooltips and docs)."""

import re
from pathlib import Path

import bpy
import pytest

from blender_support import MODULE, ROOT

#: The papers' terms that must not appear in labels, names, reports and warnings.
PAPER_TERMS = re.compile(r"\beq\.\s*\d|\brank of A\b|\bTable 1\b", re.IGNORECASE)
#: What a docstring leaves in a tooltip when Blender takes it verbatim.
STRAY_BREAK = re.compile(r"\n|\s{2,}")


def _our_classes():
    found = []
    for base in (bpy.types.Operator, bpy.types.Panel, bpy.types.Menu, bpy.types.PropertyGroup,
                 bpy.types.AddonPreferences, bpy.types.FileHandler):
        found += [c for c in base.__subclasses__()
                  if c.__module__.startswith(MODULE) and getattr(c, "is_registered", False)]
    return found


def _properties(rna):
    return [p for p in rna.properties if p.identifier not in ("rna_type", "name", "bl_idname")]


def _registered_texts():
    """(where, label texts, description texts) of everything the extension registers."""
    out = []
    for cls in _our_classes():
        rna = cls.bl_rna
        if issubclass(cls, bpy.types.Operator):
            module, name = cls.bl_idname.split(".")
            rna = getattr(getattr(bpy.ops, module), name).get_rna_type()
        labels = [rna.name] + [getattr(cls, "bl_label", "")]
        descriptions = [rna.description] if issubclass(cls, bpy.types.Operator) else []
        own = (bpy.types.Operator, bpy.types.PropertyGroup, bpy.types.AddonPreferences)
        if not issubclass(cls, own):        # panels, menus: Blender's own properties
            out.append((cls.__name__, labels, descriptions))
            continue
        for prop in _properties(rna):
            if prop.is_hidden:
                continue
            labels.append(prop.name)
            descriptions.append(prop.description)
            for item in getattr(prop, "enum_items", ()):
                labels.append(item.name)
                descriptions.append(item.description)
        out.append((cls.__name__, labels, descriptions))
    return out


def test_the_scan_sees_the_tracking_and_gait_classes():
    names = {where for where, _, _ in _registered_texts()}
    assert {"TS_OT_track_keyframes", "TS_OT_suggest_keyframes", "TS_TrackSettings",
            "TS_OT_predict_gait"} <= names


def test_every_description_is_one_clean_line():
    bad = [(where, d) for where, _, descriptions in _registered_texts()
           for d in descriptions if d and STRAY_BREAK.search(d)]
    assert not bad, bad
    missing = [where for where, _, descriptions in _registered_texts()
               if any(not d for d in descriptions)]
    assert not missing, missing


def test_no_label_uses_the_papers_terms():
    bad = [(where, label) for where, labels, _ in _registered_texts()
           for label in labels if label and PAPER_TERMS.search(label)]
    assert not bad, bad


@pytest.mark.parametrize("folder", ["addon", "sample_scenes", "tools"])
def test_no_user_visible_string_in_the_sources_uses_the_papers_terms(folder):
    """Strings that reach the user -- reports, warnings, labels, marker and curve names, the
    demo pictures' labels -- are found as string literals outside docstrings, comments and
    ``description=`` tooltips (where the papers' terms belong)."""
    bad = []
    for path in sorted((Path(ROOT) / folder).rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        for lineno, line in enumerate(text.splitlines(), 1):
            code = line.split("#", 1)[0]
            for literal in re.findall(r"f?\"([^\"]*)\"|f?'([^']*)'", code):
                literal = "".join(literal)
                if PAPER_TERMS.search(literal):
                    bad.append(f"{path.relative_to(ROOT)}:{lineno}: {literal}")
    bad = [b for b in bad if not _is_tooltip_or_docstring(b)]
    assert not bad, bad


def _is_tooltip_or_docstring(hit):
    """Tooltips (``description=`` arguments, ``bl_description``, the tooltip lines of a
    property's ``id_properties_ui``) may cite the paper."""
    path, lineno, _ = hit.split(":", 2)
    lines = (Path(ROOT) / path).read_text(encoding="utf-8").splitlines()
    context = "\n".join(lines[max(0, int(lineno) - 4):int(lineno)])
    return bool(re.search(r"description\s*=|bl_description|_TOOLTIP", context))


#: The papers' names for things: a tooltip may cite them, in parentheses after plain words.
JARGON = re.compile(r"\bEM\b|\beq\.\s*\d|singular value|z-score|\bMAD\b|photometric|\brank\b|"
                    r"training sequence|autocorrelation|Table 1", re.IGNORECASE)
#: Labels never show these either (issue 26: "DOF: 63 rotation axes", "Rank Threshold").
LABEL_JARGON = re.compile(r"\bDOF\b|\bRank\b|\bEM\b|\bMAD\b")


def _outside_parentheses(text):
    """``text`` without its parenthesised parts (nested ones too)."""
    previous = None
    while previous != text:
        previous, text = text, re.sub(r"\([^()]*\)", "", text)
    return text


def test_tooltips_cite_the_papers_terms_only_in_parentheses():
    bad = [(where, d) for where, _, descriptions in _registered_texts()
           for d in descriptions if d and JARGON.search(_outside_parentheses(d))]
    assert not bad, bad


def test_labels_use_no_abbreviations_of_the_maths():
    bad = [(where, label) for where, labels, _ in _registered_texts()
           for label in labels if label and LABEL_JARGON.search(label)]
    assert not bad, bad


def test_panel_labels_in_the_sources_use_no_abbreviations_of_the_maths():
    """``label(text=…)`` and ``prop(…, text=…)`` strings of the panels."""
    bad = []
    for path in sorted((Path(ROOT) / "addon").rglob("*.py")):
        for lineno, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for text in re.findall(r"text=f?\"([^\"]*)\"", line):
                if LABEL_JARGON.search(text) or JARGON.search(_outside_parentheses(text)):
                    bad.append(f"{path.relative_to(ROOT)}:{lineno}: {text}")
    assert not bad, bad


def _raised_messages(path):
    """(line, text) of every string literal inside a ``raise`` statement of ``path``."""
    import ast
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Raise) and node.exc is not None:
            for part in ast.walk(node.exc):
                if isinstance(part, ast.Constant) and isinstance(part.value, str):
                    out.append((part.lineno, part.value))
    return out


@pytest.mark.parametrize("folder", ["core", "addon"])
def test_error_messages_use_an_animators_words(folder):
    """What a refusal says reaches the animator (reports, the command line's JSON): none of
    the maths' names, even in parentheses ("training sequence 0", "autocorrelation has no
    positive peak", NumPy's allow_pickle advice)."""
    words = re.compile(r"training sequence|autocorrelation|allow_pickle|Table 1|\bMAD\b",
                       re.IGNORECASE)
    bad = [f"{path.relative_to(ROOT)}:{line}: {text}"
           for path in sorted((Path(ROOT) / folder).rglob("*.py"))
           for line, text in _raised_messages(path) if words.search(text)]
    assert not bad, bad


def test_confidence_curves_have_names_an_animator_reads_and_old_files_still_work():
    """The Graph Editor showed ``track_and_stride_residual`` / ``_rank`` (issue 26); files
    tracked then keep working: the old curve is read, and replaced when tracked again."""
    import importlib

    import numpy as np

    keys = importlib.import_module(f"{MODULE}.addon.tracking.keys")
    fcurves = importlib.import_module(f"{MODULE}.addon.common.fcurves")
    obj = bpy.data.objects.new("Walker", None)
    bpy.context.scene.collection.objects.link(obj)
    action, slot = fcurves.ensure_action(obj, "Walker")
    bag = fcurves.channelbag(action, slot, ensure=True)
    obj["track_and_stride_residual"] = 0.0                        # as an earlier version wrote
    old = bag.fcurves.new('["track_and_stride_residual"]', index=0)
    old.keyframe_points.add(2)
    old.keyframe_points.foreach_set("co", [2.0, 0.5, 3.0, 0.7])
    frames, values = keys.read_residuals(obj, 1, 10)
    assert frames.tolist() == [2, 3] and np.allclose(values, [0.5, 0.7])
    assert keys.has_confidence(obj)
    keys.write_confidence(obj, bag, [2, 3, 4], [0.1, 0.2, 0.3], [5, 6, 4], 6)
    paths = sorted(f.data_path for f in bag.fcurves)
    assert paths == ['["Footage Mismatch"]', '["Movements Seen"]']
    assert not any(k.startswith("track_and_stride_") for k in obj.keys())
    assert keys.read_residuals(obj, 1, 10)[0].tolist() == [2, 3, 4]
    for name, better in (("Footage Mismatch", "lower is better"),
                         ("Movements Seen", "higher is better")):
        tooltip = obj.id_properties_ui(name).as_dict()["description"]
        assert better in tooltip and not JARGON.search(_outside_parentheses(tooltip)), tooltip
