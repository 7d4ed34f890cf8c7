"""The live PRT display: shader, GPU cache, albedo, lighting, drawing, offscreen renders."""
