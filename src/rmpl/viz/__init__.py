"""Pictures: static skeleton and reprojection plots (``plots``), the HTML 3D viewer (``viewer``)."""
