"""Programs that are not the library: they use toaster as its users do."""
