"""Scene data shared by the bake and the display: meshes read, stored bakes, lighting, materials, occluders."""
