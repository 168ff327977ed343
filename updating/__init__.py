"""updating package."""
