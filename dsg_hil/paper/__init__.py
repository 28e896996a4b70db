"""The paper's reproduction: reference numbers, the Section III.C validation, calibration, the reduced creep model,
figures and the report. Downstream of everything: nothing in the loop imports it."""
