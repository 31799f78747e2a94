"""The table of drone platforms: every entry read, plausible, with its source; unknown names
and broken entries refused naming the field."""

from __future__ import annotations

from pathlib import Path

import pytest

from turbinefit.errors import InputError
from turbinefit.io.platforms import (
    DEFAULT_PLATFORM,
    MISSION_FORMATS,
    drone_platform,
    drone_platforms,
)


def test_every_platform_is_plausible_and_sourced() -> None:
    table = drone_platforms()
    assert DEFAULT_PLATFORM in table and len(table) >= 8
    for key, p in table.items():
        assert p.source.strip(), key
        assert set(p.formats) <= set(MISSION_FORMATS) and "kml" in p.formats, key
        assert p.gimbal_min_deg <= -90.0 and 0.0 <= p.gimbal_max_deg <= 90.0, key
        assert 2 <= p.max_waypoints <= 65535 and 0 < p.max_speed_m_s <= 25, key
        # DJI WPML needs DJI's enumeration values of the aircraft and payload
        assert ("dji-wpml" in p.formats) == bool(p.wpml), key
        if p.camera is not None:
            w, h, fx, fy, cx, cy = p.camera.intrinsics()
            # 35 mm equivalent focal lengths of 20-60 mm: wide cameras
            assert 20.0 < 36.0 * p.camera.focal_length_mm / p.camera.sensor_width_mm < 60.0, key
            assert fx == fy and cx == (w - 1) / 2 and cy == (h - 1) / 2


def test_the_default_is_within_every_dji_gimbal() -> None:
    """generic: no DJI gimbal of the table tilts up less than it asks."""
    generic = drone_platform(DEFAULT_PLATFORM)
    dji = [p for p in drone_platforms().values() if "DJI" in p.name]
    assert len(dji) >= 6
    assert generic.gimbal_max_deg <= min(p.gimbal_max_deg for p in dji)
    assert generic.gimbal_max_deg == 20.0
    assert generic.max_waypoints <= min(p.max_waypoints for p in dji) == 99


def test_an_unknown_platform_names_the_known_ones() -> None:
    assert drone_platform(" M30T ").key == "m30t"
    with pytest.raises(InputError, match=r"^--platform: unknown platform 'm31t'; known: .*m30t"):
        drone_platform("m31t")


@pytest.mark.parametrize("entry, field", [
    ("{name: x, formats: [kml], gimbal_pitch_deg: [-60, 30], max_waypoints: 99, "
     "max_speed_m_s: 10, source: s}", r"x\.gimbal_pitch_deg"),
    ("{name: x, formats: [kml], gimbal_pitch_deg: [-90, 30], max_waypoints: 1, "
     "max_speed_m_s: 10, source: s}", r"x\.max_waypoints"),
    ("{name: x, formats: [dji], gimbal_pitch_deg: [-90, 30], max_waypoints: 99, "
     "max_speed_m_s: 10, source: s}", r"x\.formats"),
    ("{name: x, formats: [kml], gimbal_pitch_deg: [-90, 30], max_waypoints: 99, "
     "source: s}", r"\[x\]: missing max_speed_m_s"),
])
def test_a_broken_entry_is_refused_naming_its_field(entry: str, field: str,
                                                   tmp_path: Path) -> None:
    path = tmp_path / "platforms.yaml"
    path.write_text(f"x: {entry}\n")
    with pytest.raises(InputError, match=field):
        drone_platforms.__wrapped__(path)


def test_a_platforms_camera_is_the_camera_tables(tmp_path: Path) -> None:
    # the lens and sensor come from the importer's camera table (one place, with sources);
    # a camera it does not hold, or a zoom lens, is refused naming the entry
    from turbinefit.errors import InputError
    from turbinefit.io.dji_cameras import dji_cameras
    from turbinefit.io.platforms import drone_platforms

    cams = {c.name: c for c in dji_cameras()}
    for key, p in drone_platforms().items():
        if p.camera is not None:
            c = cams[p.camera.name]
            assert (p.camera.focal_length_mm, p.camera.sensor_width_mm) == (
                c.focal_range_mm[0], c.sensor_width_mm), key
    text = (Path(drone_platforms.__wrapped__.__defaults__[0])  # type: ignore[attr-defined]
            .read_text().replace('name: "Matrice 30 / 30T wide"', 'name: "Matrice 31 wide"'))
    bad = tmp_path / "platforms.yaml"
    bad.write_text(text)
    with pytest.raises(InputError, match=r"\[m30t\.camera\]: 'Matrice 31 wide' is not a camera"):
        drone_platforms.__wrapped__(bad)  # type: ignore[attr-defined]
