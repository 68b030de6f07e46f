"""Section 4 of the paper plus the 3-D state: probability map, clustering, tracking, ground state, warnings."""
