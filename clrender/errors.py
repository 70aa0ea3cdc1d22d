"""Errors shared across clrender's modules."""


class SceneError(ValueError):
    """Bad scene input; the message names the file (when there is one) and the problem."""
