"""scene tool."""
