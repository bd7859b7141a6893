"""Every file format lives here: calibration, 2D keypoints in, 3D poses out."""
