"""entities subpackage."""
