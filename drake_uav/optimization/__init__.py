"""MathematicalProgram formulations (trim, minimum snap, terminal sets, NMPC)."""
