"""Exceptions that the command line turns into exit codes (SPEC §1)."""


class CollideError(Exception):
    """Base class of collide's own errors."""


class InputError(CollideError):
    """Bad input: exit code 2.

    The message reads ``<file>[:<dataset>]: <problem>; expected <what>``.
    """

    def __init__(self, file, problem, expected=None, dataset=None):
        self.file = str(file)
        self.dataset = dataset
        self.problem = problem
        self.expected = expected
        where = self.file if dataset is None else f"{self.file}:{dataset}"
        text = f"{where}: {problem}"
        if expected:
            text += f"; expected {expected}"
        super().__init__(text)


class UsageError(CollideError):
    """A valid input asked for something collide cannot do: exit code 2."""
