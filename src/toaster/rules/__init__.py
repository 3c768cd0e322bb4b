"""The belief rule as the database runs it: the steps' SQL, the pipeline, the triggers and the
hook that runs the rules in the store's transaction."""
