"""The paper's models: pure functions and frozen dataclasses over numpy arrays (no file I/O)."""
