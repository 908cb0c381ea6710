"""The dataset error: what every reader raises on bad input."""


class DatasetError(ValueError):
    """Bad dataset input; the message names the file, the field and the fix."""
