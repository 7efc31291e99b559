"""hingelab stage."""
