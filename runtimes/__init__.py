"""lbscene."""
