"""The policy format's error, below the format's modules so that each raises it (its public home: ``format``)."""


class PolicyFormatError(ValueError):
    """A policy folder or file is missing, malformed, or does not describe a loadable policy."""
