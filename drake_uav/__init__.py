"""drake_uav: small unmanned aircraft on Drake.

Plants, wind, sensors, estimators, aerodynamic identification and control, each
a Drake ``LeafSystem`` or ``MathematicalProgram``. See README.md for a tour.
"""

__version__ = "0.1.0"
