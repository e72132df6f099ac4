"""Exception hierarchy of euc_ros.

Every error the user can cause is an :class:`EucError`. Its message names what to fix: the file,
line, column or key. The CLI maps it to one line on stderr and exit code 2; nodes catch it at the
callback boundary, count it and keep running.
"""
from __future__ import annotations

from pathlib import Path


class EucError(Exception):
    """Base class of all errors the user can cause (bad input, bad config)."""


class InputError(EucError, ValueError):
    """Malformed input data, located by path, line, column and/or key.

    Parameters
    ----------
    message : str
        What is wrong and, where possible, how to fix it.
    path : str or Path, optional
        File the error is in.
    line : int, optional
        1-based line number.
    column : int or str, optional
        1-based column number or column name.
    key : str, optional
        Dotted key (``rider.segments.H.mass_fraction``) for structured files.
    """

    def __init__(self, message: str, *, path: str | Path | None = None, line: int | None = None,
                 column: int | str | None = None, key: str | None = None) -> None:
        self.path = None if path is None else str(path)
        self.line = line
        self.column = column
        self.key = key
        self.detail = message
        super().__init__(self._format())

    def _format(self) -> str:
        where = []
        if self.path is not None:
            where.append(self.path)
        if self.line is not None:
            where.append(f"line {self.line}")
        if self.column is not None:
            where.append(f"column {self.column}")
        if self.key is not None:
            where.append(f"key '{self.key}'")
        return (": ".join([", ".join(where), self.detail]) if where else self.detail)


class ConfigError(InputError):
    """Invalid configuration: session file, params file or command-line options.

    Parameters
    ----------
    message : str
        What is wrong and, where possible, how to fix it.
    path : str or Path, optional
        File the error is in.
    line : int, optional
        1-based line number.
    column : int or str, optional
        1-based column number or column name.
    key : str, optional
        Dotted key for structured files.
    """


class ModelDomainError(EucError):
    """A state left the domain where a model is valid (e.g. tilt near 90 deg)."""


def describe_error(exc: BaseException) -> str:
    """One line for a failed task's row: ``"Type: message"``, or the traceback's last line when there is no message.

    Parameters
    ----------
    exc : BaseException
        The exception the task raised (being handled).

    Returns
    -------
    str

    Examples
    --------
    >>> describe_error(InputError("no recording given", key="recordings"))
    "InputError: key 'recordings': no recording given"
    """
    import traceback

    return f"{type(exc).__name__}: {exc}" if str(exc) else traceback.format_exc(limit=1).strip()
