"""What every part of dsg-hil and ecu-stub shares: the error tree and exit codes, file helpers, units, lazy names.

Light by design (standard library only): ecu-stub may import it, and a command's ``--help`` loads it.
"""
