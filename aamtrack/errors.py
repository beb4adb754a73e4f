"""Exceptions raised on bad input. The CLI turns each into one line on stderr and a non-zero exit."""


class AamtrackError(Exception):
    """Base class: bad input or an unusable file. The message names the file and what is wrong."""


class InputError(AamtrackError):
    """A missing, unreadable or malformed input (image, video, .pts, mesh, folder)."""


class ModelFileError(AamtrackError):
    """A model file that is missing, corrupt, or of a format version this package cannot read."""


class OutputError(AamtrackError):
    """An output that cannot be written (no video encoder, unwritable folder)."""
