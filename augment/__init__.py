"""augment package (see DESIGN.md)."""
