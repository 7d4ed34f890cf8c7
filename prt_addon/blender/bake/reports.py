"""Where the last bake's report is kept (the scene, or memory for bakes that changed nothing)
and how it is told to the operator's caller."""

import json

# Reports of bakes that changed nothing (refused, failed, cancelled) are kept in memory only, so
# that a refused bake leaves the .blend exactly as it was; a finished bake saves its report in
# scene.prt_bake.last_report (it changed the file anyway).
_unsaved_reports = {}  # scene.session_uid -> report dict


def _scene_key(scene):
    return getattr(scene, "session_uid", None) or scene.as_pointer()


def _remember_unsaved(key, report):
    _unsaved_reports[key] = report.as_dict()


def _store_report(scene, report):
    if not report.ok:
        _remember_unsaved(_scene_key(scene), report)
        return
    _unsaved_reports.pop(_scene_key(scene), None)
    settings = getattr(scene, "prt_bake", None)
    if settings is not None:
        settings.last_report = json.dumps(report.as_dict())


def last_report(scene):
    """The report (a dict, see BakeReport.as_dict) of the last bake in this scene, or None: that
    of a bake that changed nothing this session if there is one, else the saved one."""
    data = _unsaved_reports.get(_scene_key(scene))
    if data is not None:
        return dict(data)
    saved = getattr(getattr(scene, "prt_bake", None), "last_report", "")
    if not saved:
        return None
    try:
        return json.loads(saved)
    except ValueError:
        return None


def _report_to_operator(op, report):
    if report.ok:
        op.report({"INFO"}, "PRT: " + report.headline())
    if report.note:
        op.report({"WARNING"}, f"PRT: {report.note}")
    for note in report.albedo_notes:  # bounced light: how materials were read, clamped albedos
        op.report({"WARNING"} if "clamped" in note else {"INFO"}, f"PRT: {note}")
    for name, reason in report.skipped:
        op.report({"WARNING"}, f"PRT: skipped '{name}': {reason}")
