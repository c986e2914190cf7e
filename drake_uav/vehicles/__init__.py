"""Vehicle parameter dataclasses and the catalog of known aircraft."""
