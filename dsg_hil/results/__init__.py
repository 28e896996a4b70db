"""What a run gives, from a trace or a decoded log: the creep metrics and the run summary (no clock, no bus)."""
