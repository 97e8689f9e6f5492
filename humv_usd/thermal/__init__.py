"""thermal tool."""
