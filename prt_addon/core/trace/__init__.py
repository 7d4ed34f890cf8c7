"""Ray tracing: the Embree occluder, its shared buffers, the occluder protocol and its lazy builder, ray rows."""
