"""Synthetic drives: a textured 3-D world rendered through the camera model, written as recordings with truth."""
