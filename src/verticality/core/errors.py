"""Errors a user can fix. The CLI prints them as one line and exits with status 2."""


class InputError(ValueError):
    """Bad input (file, column, value or option), described in one line for the user."""
