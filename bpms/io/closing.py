"""The ``with`` block of everything that has a ``close()``: files, links, sockets, writers."""

from __future__ import annotations

from typing import Self


class Closing:
    """``with obj as o:`` gives ``obj`` itself and calls ``obj.close()`` when the block ends,
    whether or not it raised."""

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
