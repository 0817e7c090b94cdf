"""Filters as pure step functions on typed records."""
