"""Section 2-3 of the paper: geometry, prior motion, optical flow, refinement, detection. Pure functions, no I/O."""
