"""Notes: the warnings of a computation, which a caller may take as values instead.

`note(message, category)` issues a warning, as `warnings.warn` does; inside
`collecting_notes()` it appends the note to the list that context gives instead. The
collection is a context variable: each thread has its own, so a study's theory thread takes
its own notes while the simulations beside it warn as usual, without touching `warnings`.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import warnings
from collections.abc import Iterator


@dataclasses.dataclass(frozen=True)
class Note:
    """One note: its text (`message`, as `str(warning.message)`) and warning `category`."""

    message: str
    category: type[Warning] = UserWarning

    def __str__(self) -> str:
        return self.message


_collecting: contextvars.ContextVar[list[Note] | None] = contextvars.ContextVar(
    "stickslip_notes", default=None
)


def note(message: str, category: type[Warning] = UserWarning, stacklevel: int = 1) -> None:
    """Warn with `message` (`stacklevel` as `warnings.warn` counts it from the caller), or
    append it to the notes being collected in this context."""
    collected = _collecting.get()
    if collected is not None:
        collected.append(Note(str(message), category))
        return
    warnings.warn(message, category, stacklevel=stacklevel + 1)


@contextlib.contextmanager
def collecting_notes() -> Iterator[list[Note]]:
    """The notes `note` makes in this context (this thread), as a list, instead of
    warnings; nested, the inner collection takes them."""
    collected: list[Note] = []
    token = _collecting.set(collected)
    try:
        yield collected
    finally:
        _collecting.reset(token)
