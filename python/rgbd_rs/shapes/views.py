"""The six orthographic depth views of a shape (thesis §5.3.1)."""
