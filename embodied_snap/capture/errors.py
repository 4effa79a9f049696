"""The one error the capture readers raise."""

from __future__ import annotations


class CaptureError(ValueError):
    """An export this package refuses to read: one line, `<file>: <what was found> (rule: <rule>)`."""

    def __init__(self, path, what: str, rule: str):
        self.path, self.what, self.rule = path, " ".join(str(what).split()), " ".join(str(rule).split())
        super().__init__(f"{path}: {self.line}")

    @property
    def line(self) -> str:
        """What was found and the rule it breaks, without the file."""
        return f"{self.what} (rule: {self.rule})"

    def __reduce__(self):  # picklable across worker processes
        return (type(self), (self.path, self.what, self.rule))
