"""Pure physics of the DSG creep plant: no I/O, SI units (temperatures in degC), equation numbers of the paper."""
