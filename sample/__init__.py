"""sample package (see DESIGN.md)."""
