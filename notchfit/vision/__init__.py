"""Camera model, synthetic images and the notch-corner detector (below file I/O)."""
