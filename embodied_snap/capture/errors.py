"""The one error the capture readers raise."""

from __future__ import annotations


class CaptureError(ValueError):
    """An export this package refuses to read: one line, naming the file and the rule broken."""

    def __init__(self, path, rule: str):
        self.path, self.rule = path, " ".join(str(rule).split())
        super().__init__(f"{path}: {self.rule}")

    def __reduce__(self):  # picklable across worker processes
        return (type(self), (self.path, self.rule))
