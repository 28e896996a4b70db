"""The package's exceptions and exit codes: see :mod:`dsg_hil.protocol.errors` (shared with ecu-stub)."""

from .protocol.errors import (  # noqa: F401
                              EXIT_BAD_INPUT,
                              EXIT_OK,
                              EXIT_OUT_OF_BAND,
                              EXIT_RUN_FAILED,
                              EXIT_SIGINT,
                              EXIT_SIGTERM,
                              DsgHilError,
                              InputError,
                              ResultError,
                              RunError,
                              exit_code,
                              read_input_file,
)
