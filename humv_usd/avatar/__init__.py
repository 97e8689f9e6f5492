"""avatar tool."""
