"""What a study of one machine or of many is, as results: the machine study, sweeps, profile
and correlation comparisons, timing."""
