"""Synthetic studies from recipes (reads recipes and writes studies through notchfit.io)."""
