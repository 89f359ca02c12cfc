"""Exceptions with messages meant for engineers: what was wrong and what is accepted."""


class DampersimError(Exception):
    """Base class of every error dampersim raises on purpose."""


class ParameterError(DampersimError, ValueError):
    """A parameter (or input) is unknown or has an impossible value.

    ``field`` is the dotted name (``outer.spring.stiffness``), ``value`` what was given
    and ``accepted`` a short description of what would be valid.
    """

    def __init__(self, field, value, accepted, hint=""):
        self.field = field
        self.value = value
        self.accepted = accepted
        self.hint = hint
        msg = f"{field} = {value!r}: accepted is {accepted}"
        if hint:
            msg += f" ({hint})"
        super().__init__(msg)

    def __reduce__(self):  # survive pickling across process pools and Dask workers
        return (type(self), (self.field, self.value, self.accepted, self.hint))


class InputError(DampersimError, ValueError):
    """Bad user input that is not a model parameter (orders string, file, option)."""


class SimulationDiverged(DampersimError, RuntimeError):
    """The integration produced NaN or runaway values; ``time`` [s] is when."""

    def __init__(self, time, reason, time_step):
        self.time = time
        self.reason = reason
        self.time_step = time_step
        super().__init__(
            f"simulation diverged at t = {time:.6f} s ({reason}); "
            f"try a smaller time step than {time_step:g} s (--set solver.time_step=...)"
        )

    def __reduce__(self):
        return (type(self), (self.time, self.reason, self.time_step))


class AccuracyWarning(UserWarning):
    """A setting is allowed but outside what dampersim's accuracy checks cover (e.g. a
    time step above the accuracy-tested default): results may carry larger errors."""
