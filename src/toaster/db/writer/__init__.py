"""The write path: the store, the change records it hands rules, the batch diff and the
conflict retry."""
