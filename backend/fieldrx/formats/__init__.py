"""Import and export formats: GeoJSON, Table 1 CSV, zipped Shapefile, ISO 11783-10, job package."""


class FormatError(ValueError):
    """A file cannot be read or written; the message says where (feature index, file, field)."""

