"""Synthetic drives: a textured 3-D world through the camera model, as recordings with truth."""
