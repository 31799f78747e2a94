"""GeoJSON (RFC 7946) twins of the CSV files that give WGS84 positions, and the sidecar
files that let GIS tools open such a CSV as points without being asked.

:func:`csv_to_geojson` turns a CSV's text with ``latitude``, ``longitude`` and
``altitude`` columns into a ``FeatureCollection`` of ``Point`` features, one per row, in
the same order: ``[longitude, latitude, altitude]`` (RFC 7946 section 3.1.1; its CRS is
always WGS84 longitude-latitude, so no ``crs`` member), the other columns as properties
(numbers as numbers, empty cells as null); a row with no position has a null geometry
(section 3.2). :func:`write_geojson_twin` writes it next to the CSV as ``<stem>.geojson``.

:func:`write_csv_sidecars` writes GDAL's sidecars of a CSV (GDAL's CSV driver, which QGIS
opens CSVs with; https://gdal.org/drivers/vector/csv.html): ``<stem>.csvt``, the column
types, with ``CoordX`` for the longitude and ``CoordY`` for the latitude (the GeoCSV
convention GDAL follows), so the rows open as points; and ``<stem>.prj``, the WKT of
EPSG:4326, so they open in WGS84 without asking.

Written with :mod:`json` and :mod:`csv`: a point collection is a few fixed keys (the
``geojson`` package would add a dependency for a dictionary).
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any

from turbinefit.io.atomic import write_text_atomic

#: EPSG:4326 (WGS 84, geographic 2-D) as GDAL writes it in WKT 1, with its EPSG
#: authority codes (so GDAL and QGIS name it EPSG:4326 rather than a custom CRS).
WGS84_PRJ = ('GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,'
             'AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,'
             'AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,'
             'AUTHORITY["EPSG","9122"]],AXIS["Latitude",NORTH],AXIS["Longitude",EAST],'
             'AUTHORITY["EPSG","4326"]]')


def _value(text: str) -> Any:
    if text == "":
        return None
    try:
        v = float(text)
    except ValueError:
        return text
    if not math.isfinite(v):
        return None
    return int(v) if v.is_integer() and "." not in text and "e" not in text.lower() else v


def csv_to_geojson(text: str, latitude: str = "latitude", longitude: str = "longitude",
                   altitude: str = "altitude") -> str:
    """The GeoJSON ``FeatureCollection`` of a CSV's rows (module docstring)."""
    reader = csv.DictReader(io.StringIO(text))
    features = []
    for row in reader:
        props = {k: _value(v) for k, v in row.items()}
        lat, lon, alt = (props.get(k) for k in (latitude, longitude, altitude))
        geometry = None
        if isinstance(lat, int | float) and isinstance(lon, int | float):
            coords = [lon, lat] + ([alt] if isinstance(alt, int | float) else [])
            geometry = {"type": "Point", "coordinates": coords}
        features.append({"type": "Feature", "geometry": geometry, "properties": props})
    return json.dumps({"type": "FeatureCollection", "features": features},
                      separators=(",", ":")) + "\n"


def write_geojson_twin(csv_path: Path, text: str) -> Path:
    """Write :func:`csv_to_geojson` of ``text`` (the CSV written at ``csv_path``) as
    ``csv_path``'s ``.geojson`` twin; returns its path."""
    return write_text_atomic(csv_path.with_suffix(".geojson"), csv_to_geojson(text),
                             fsync=False)


def csvt_line(header: str, types: dict[str, str]) -> str:
    """The ``.csvt`` line of a CSV whose header is ``header``: each column's type from
    ``types`` (``"Real"``, ``"Integer"``, ``"CoordX"`` ...), ``"String"`` if not given."""
    return ",".join(f'"{types.get(name, "String")}"' for name in header.split(",")) + "\n"


def write_csv_sidecars(csv_path: Path, header: str, types: dict[str, str]) -> None:
    """Write ``csv_path``'s ``.csvt`` (:func:`csvt_line`) and ``.prj`` (EPSG:4326)."""
    write_text_atomic(csv_path.with_suffix(".csvt"), csvt_line(header, types), fsync=False)
    write_text_atomic(csv_path.with_suffix(".prj"), WGS84_PRJ + "\n", fsync=False)
