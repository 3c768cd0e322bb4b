"""Perspective taking: every non-self agent's beliefs, maintained by rules in the database."""
