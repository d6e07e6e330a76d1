"""Robot data shipped with calib: the catalog and the project's own URDFs."""
