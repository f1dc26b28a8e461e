"""The one exception family of bench: every error a user can cause or meet derives from BenchError.

Messages name the place, the field, the value and what was expected, e.g.
``pose_test.toml: cycles = 0, expected an integer >= 1``. The CLI prints them as one line:
exit code 2 for bad input (``ConfigError``, ``UnreachableTarget``), 1 for failures at run time.
"""


class BenchError(Exception):
    """Base of all errors bench raises on purpose."""

    exit_code = 1


class ConfigError(BenchError):
    """Bad user input: a parameter, a file, a command-line value."""

    exit_code = 2


class UnreachableTarget(BenchError):
    """A target pose failed the pre-flight check (reach, joint limits, singularity)."""

    exit_code = 2


class InsufficientData(BenchError):
    """Too few samples for a statistic (e.g. fewer cycles than a formula needs)."""


class LinkError(BenchError):
    """The serial link to a controller or sensor failed or answered with an error."""


class LinkTimeout(LinkError):
    """A reply did not arrive before its deadline."""


class PromptWithdrawn(BenchError):
    """The operator withdrew a prompt instead of answering it (Cancel in the window, the window closed).

    An :class:`bench.rigs.interfaces.Operator` raises it from ``ask``; the runner then ends the run at once as
    ``aborted`` (resumable, no clean-up moves, since the operator may be at the robot) with the reason
    "prompt withdrawn by the operator: <prompt text> (<this message>)".
    """
