"""Import and export formats: GeoJSON, Table 1 CSV, zipped Shapefile, ISO 11783-10, job package."""


class FormatError(ValueError):
    """A file cannot be read or written; the message says where (feature index, file, field)."""


EXPORT_FORMATS = ("geojson", "csv", "shapefile", "isoxml", "isoxml-zones", "job")
MEDIA_TYPES = {
    "geojson": ("application/geo+json", "prescription.geojson"),
    "csv": ("text/csv", "prescription.csv"),
    "shapefile": ("application/zip", "prescription_shp.zip"),
    "isoxml": ("application/zip", "TASKDATA.zip"),
    "isoxml-zones": ("application/zip", "TASKDATA.zip"),
    "job": ("application/json", "job.json"),
}
