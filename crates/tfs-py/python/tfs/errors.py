"""Exceptions raised by tfs. Every message is the one the CLI prints for the same problem."""

__all__ = ["TfsError", "InputError", "SimulationError"]


class TfsError(Exception):
    """Base of every tfs error."""


class InputError(TfsError, ValueError):
    """Bad input: a file, a column, a row or an argument (the message names it and says what to do)."""


class SimulationError(TfsError):
    """A simulation blew up. ``t`` is the time (s) and ``x``, ``v`` the state where it happened."""

    def __init__(self, message, t, x, v):
        super().__init__(message, t, x, v)
        self.message = message
        self.t = t
        self.x = list(x)
        self.v = list(v)

    def __str__(self):
        return self.message
