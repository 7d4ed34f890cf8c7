"""Property groups and sidebar panels."""
