"""Function approximators: local linear regression (LLR, section 4) and tile coding (sec. 6.1)."""
