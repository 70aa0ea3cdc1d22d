"""Every exception type clrender raises, in one module below all others: a caller (the CLI, a
batch worker) recognises an error by its class without importing the layer that raised it
(DeviceError without pyopencl). The modules that raise them re-export their names."""


class SceneError(ValueError):
    """Bad scene input; the message names the file (when there is one) and the problem."""


class BudgetError(SceneError):
    """A count read from a file would take more memory than the budget allows."""


class DeviceError(RuntimeError):
    """No OpenCL device matches, none is installed, or a program does not build on it."""


class DeviceMemoryError(ValueError):
    """The requested frame or scene does not fit the device's memory."""


class OutputError(OSError):
    """Writing an output file failed: the message names the output (never its temporary file)."""


class CLIError(Exception):
    """A user-facing error of the command line: printed as one line, exit status `code`."""

    def __init__(self, message: str, code: int = 1):
        super().__init__(message)
        self.code = code


class OutputOverInput(CLIError):
    """An output path is a file the job reads."""
