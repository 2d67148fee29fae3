"""Output-error identification (filled in below)."""
