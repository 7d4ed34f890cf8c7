"""A stand-in for a panel's UILayout that records what draw() puts in it, for the panel tests."""


class RecordingLayout:
    """Stands in for a panel's UILayout: records what draw() puts in it (props with their text)."""

    def __init__(self, log):
        self.log = log

    def prop(self, data, name, text=None, **_kw):
        self.log.append(("prop", name, text))

    def label(self, text="", **_kw):
        self.log.append(("label", text))

    def operator(self, idname, text=None, **_kw):
        self.log.append(("operator", idname, text))

    def row(self, **_kw):
        return self

    column = row


def labels(log):
    """The texts of the labels in a RecordingLayout's log."""
    return [entry[1] for entry in log if entry[0] == "label"]
