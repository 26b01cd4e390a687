"""The one error type of scenario handling, with the file and key path a user must fix."""

from __future__ import annotations

__all__ = ["ScenarioError"]


class ScenarioError(ValueError):
    """A scenario that cannot be run, described on one line.

    Parameters
    ----------
    reason : str
        What is wrong and, where possible, how to fix it.
    file : str, optional
        The scenario's file path, bundled name or ``"<inline>"``.
    key : str, optional
        Key path inside the document, e.g. ``"bodies[1].m"`` or ``"output.every"``.
    line : int, optional
        1-based line of the offending key in the YAML file, when known.

    Notes
    -----
    ``str(err)`` is ``"<file>: <key>: <reason> (line <n>)"``, parts omitted when unknown, and is
    always a single line, so the CLI can print it as is.
    """

    def __init__(self, reason: str, *, file: str | None = None, key: str | None = None,
                 line: int | None = None) -> None:
        self.reason = " ".join(str(reason).split())  # one line, whatever the cause said
        self.file = file
        self.key = key
        self.line = line
        super().__init__(self.reason)

    def __str__(self) -> str:
        parts = [p for p in (self.file, self.key) if p]
        text = ": ".join([*parts, self.reason])
        return f"{text} (line {self.line})" if self.line else text

    def located(self, file: str, lines: dict[str, int] | None = None) -> ScenarioError:
        """A copy naming ``file`` (and the line of its key) when this error did not know them."""
        line = self.line
        if line is None and lines and self.key:
            line = _line_of(self.key, lines)
        return ScenarioError(self.reason, file=self.file or file, key=self.key, line=line)


def _line_of(key: str, lines: dict[str, int]) -> int | None:
    """Line of ``key`` or of its nearest ancestor that the YAML reader recorded."""
    while key:
        if key in lines:
            return lines[key]
        cut = max(key.rfind("."), key.rfind("["))
        key = key[:cut] if cut > 0 else ""
    return None
