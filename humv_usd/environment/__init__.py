"""environment tool."""
