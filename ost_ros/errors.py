"""Error types shared by the CLI verbs."""


class UsageError(Exception):
    """Bad input from the user (file, flag, value). Printed as one line; exit code 2."""
