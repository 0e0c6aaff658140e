"""The systems of chapter 7, one factory per system, each returning a `ModelSpec`."""
