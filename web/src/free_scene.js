// An app's own GPU resources of loaded scenes freed: every geometry, material and material texture under the roots.

/** Disposes each geometry, material and texture a material holds, under every root (null roots skipped). */
export function freeScene(...roots) {
  const owned = new Set();
  for (const root of roots)
    if (root)
      root.traverse((o) => {
        if (o.geometry) owned.add(o.geometry);
        for (const material of [o.material].flat())
          if (material) {
            owned.add(material);
            for (const value of Object.values(material)) if (value && value.isTexture) owned.add(value);
          }
      });
  owned.forEach((thing) => thing.dispose());
}
