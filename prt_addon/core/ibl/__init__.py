"""Image-based lighting for export: GGX-prefiltered cube maps and the RGBD PNG encoding."""
