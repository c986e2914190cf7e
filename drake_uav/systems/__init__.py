"""Drake LeafSystems: plants, wind, sensors, excitation, estimators, identifiers."""
