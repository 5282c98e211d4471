"""The hexapod campaign summary, its figures and its report and index templates."""
