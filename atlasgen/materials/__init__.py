"""Material and scene files: parameters, validation and the parsed types."""
