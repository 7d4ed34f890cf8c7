"""Split lights: extraction from an HDRI, their samples, visibility, SH and shadow views."""
