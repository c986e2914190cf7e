"""Names of the catalog aircraft, importable without the parameter classes.

The command line checks an ``--aircraft`` argument against these before it loads
the analysis stack (a wrong name fails in well under a second);
:func:`~drake_uav.vehicles.fixed_wing.fixed_wing_catalog` builds exactly these.
"""

FIXED_WING_NAMES = ("aerosonde", "aerosonde_mavsim", "unatrap")
"""Fixed-wing catalog aircraft, by the name ``--aircraft`` and TOML ``base`` accept."""
