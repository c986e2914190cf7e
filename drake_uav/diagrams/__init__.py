"""Builders that wire systems into ready-to-simulate diagrams."""
