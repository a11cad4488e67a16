"""The estimation core under identify and diagnose (docs/architecture.md)."""
