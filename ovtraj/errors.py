"""The project's error for unusable input, at the bottom of the layers: the store, the
paths and the configuration models raise it alike (so none of them imports upward for it)."""

from __future__ import annotations

from ovtraj.formatting import printable

__all__ = ["ConfigError"]


class ConfigError(ValueError):
    """A configuration that cannot be used: one line naming the file and the field, or
    a heading and one line per offending field when there are several."""

    def __init__(self, problems: list[str], source: str = "") -> None:
        self.problems = problems
        self.source = source
        # the source is a path or a URL from the user: one printable line
        head = f"invalid configuration{f' in {printable(source)}' if source else ''}:"
        if len(problems) == 1:
            super().__init__(f"{head} {problems[0]}")
        else:
            super().__init__("\n".join([head, *(f"  - {p}" for p in problems)]))

    def __reduce__(self) -> tuple[type[ConfigError], tuple[list[str], str]]:
        # Raised in a worker process, it is pickled back: rebuilt from its problems, not
        # from the formatted message (which a list of problems would read as characters).
        return type(self), (self.problems, self.source)
