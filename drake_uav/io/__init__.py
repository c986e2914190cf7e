"""Flight logs: the FlightLog container and readers/writers for log formats."""
