"""Export of baked scenes to other engines (glTF binary with the PRT data)."""
