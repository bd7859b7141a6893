"""The training-data generator: real motion, bodies, cameras, rendering, detections, noise."""
