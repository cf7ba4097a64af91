"""Errors for bad user input: the CLI turns them into exit status 2 and one line on stderr."""

import os


class InputError(ValueError):
    """Bad input: names the offending file (or field) and says what is wrong.

    str(err) is the single line the CLI prints, "<where>: <problem>".
    """

    def __init__(self, where, problem):
        self.where = os.fspath(where) if where is not None else None
        self.problem = problem
        super().__init__(f"{self.where}: {problem}" if self.where else problem)
