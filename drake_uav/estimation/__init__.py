"""State estimation: the EKF core, its filter models and offline runs over flight logs."""
