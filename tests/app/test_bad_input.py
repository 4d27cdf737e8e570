"""Bad input (issue #11 item 3): every one is a 4xx in the JSON error shape, never a plain-text
500 or a reset connection. NaN, Infinity and 1e999 in float fields, ``true`` for a number, ids
past SQLite's integers, gains the design cannot evaluate; a catch-all for the rest."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from .conftest import Rig, make_rig

API = "/api/v1"
JSON = {"Content-Type": "application/json"}
BIG_ID = 2**63  # one past SQLite's largest integer

# (role, method, path, body with {} where the bad number goes)
FLOAT_FIELDS = [
    ("operator", "PUT", "/pointing", '{{"pan_deg": {}, "tilt_deg": 0}}'),
    ("operator", "PUT", "/pointing", '{{"pan_deg": 0, "tilt_deg": {}}}'),
    ("operator", "PUT", "/jog/pan", '{{"rate_deg_s": {}}}'),
    ("operator", "PUT", "/presets/bad", '{{"pan_deg": {}}}'),
    ("engineer", "PUT", "/axes/pan/gains", '{{"gains": {{"kp_v_per_rad": {}}}}}'),
    ("viewer", "POST", "/axes/pan/gains/preview", '{{"gains": {{"kp_v_per_rad": {}}}}}'),
    ("viewer", "POST", "/axes/pan/gains/preview", '{{"amplitude_deg": {}}}'),
    ("viewer", "POST", "/workbench/measurements/1/compare", '{{"horizon_s": {}}}'),
    ("engineer", "POST", "/practice/experiments", '{{"duration_s": {}}}'),
]
FLOAT_IDS = [
    "pointing-pan",
    "pointing-tilt",
    "jog",
    "preset",
    "gains",
    "preview-gains",
    "preview-amp",
    "compare",
    "experiment",
]


def send(rig: Rig, role: str, method: str, path: str, body: str):  # type: ignore[no-untyped-def]
    return rig.client.request(method, f"{API}{path}", headers={**rig.h(role), **JSON}, content=body)


def assert_json_error(r, status: int | tuple[int, ...]) -> dict:  # type: ignore[no-untyped-def,type-arg]
    statuses = status if isinstance(status, tuple) else (status,)
    assert r.status_code in statuses, r.text
    assert r.headers["content-type"].startswith("application/json")
    body = r.json()
    assert isinstance(body["detail"], str) and isinstance(body["error"], str)
    return body  # type: ignore[no-any-return]


@pytest.mark.parametrize("value", ["NaN", "Infinity", "-Infinity", "1e999"])
@pytest.mark.parametrize(("role", "method", "path", "template"), FLOAT_FIELDS, ids=FLOAT_IDS)
def test_non_finite_numbers_are_422(
    rig: Rig, role: str, method: str, path: str, template: str, value: str
) -> None:
    """Bug: NaN, Infinity or 1e999 in a float field made a validation error that could not be
    serialised (500, connection reset), or reached the design as a number."""
    body = assert_json_error(send(rig, role, method, path, template.format(value)), 422)
    assert body["error"] == "ValidationError"
    assert "finite" in body["detail"]


@pytest.mark.parametrize(
    ("role", "method", "path", "body"),
    [
        ("operator", "PUT", "/pointing", '{"pan_deg": 0, "tilt_deg": true}'),
        ("operator", "PUT", "/jog/tilt", '{"rate_deg_s": false}'),
        ("engineer", "PUT", "/axes/pan/gains", '{"gains": {"kp_v_per_rad": true}}'),
        ("operator", "PUT", "/pointing", '{"pan_deg": "10", "tilt_deg": 0}'),
        ("operator", "PUT", "/tracking", '{"enabled": 1}'),
        ("viewer", "POST", "/workbench/measurements/1/compare", '{"version_id": true}'),
    ],
    ids=["tilt-true", "rate-false", "gain-true", "angle-string", "enabled-1", "version-true"],
)
def test_numbers_and_booleans_are_strict(rig: Rig, role: str, method: str, path: str, body: str) -> None:
    """Bug: ``tilt_deg: true`` was accepted as 1."""
    assert assert_json_error(send(rig, role, method, path, body), 422)["error"] == "ValidationError"


@pytest.mark.parametrize(
    ("role", "method", "path", "body"),
    [
        ("viewer", "GET", f"/jobs/{BIG_ID}", None),
        ("engineer", "POST", f"/jobs/{BIG_ID}/cancel", None),
        ("viewer", "GET", f"/workbench/measurements/{BIG_ID}", None),
        ("engineer", "DELETE", f"/workbench/measurements/{BIG_ID}", None),
        ("viewer", "GET", f"/workbench/measurements/{BIG_ID}/versions", None),
        ("viewer", "POST", f"/workbench/measurements/{BIG_ID}/compare", "{}"),
        ("viewer", "GET", f"/workbench/versions/{BIG_ID}", None),
        ("viewer", "POST", "/workbench/measurements/1/compare", f'{{"version_id": {BIG_ID}}}'),
        ("engineer", "POST", "/workbench/measurements/1/fit", f'{{"version_id": {BIG_ID}}}'),
        ("engineer", "PUT", "/axes/pan/model", f'{{"version_id": {BIG_ID}}}'),
        ("engineer", "PUT", "/axes/pan/model", f'{{"version_id": {10**30}}}'),
        ("admin", "DELETE", f"/keys/{BIG_ID}", None),
    ],
    ids=[
        "job",
        "job-cancel",
        "measurement",
        "measurement-delete",
        "versions",
        "compare",
        "version",
        "compare-version",
        "fit-version",
        "put-model",
        "put-model-1e30",
        "key",
    ],
)
def test_ids_past_sqlite_integers_are_4xx(
    rig: Rig, role: str, method: str, path: str, body: str | None
) -> None:
    """Bug: ids >= 2^63 raised OverflowError in SQLite (500) on jobs, measurements, versions and
    PUT model."""
    r = rig.client.request(method, f"{API}{path}", headers={**rig.h(role), **JSON}, content=body)
    assert_json_error(r, (404, 422))


@pytest.mark.parametrize("method", ["PUT", "POST"], ids=["put", "preview"])
@pytest.mark.parametrize("value", [1e308, -1e308, 1e300], ids=["1e308", "-1e308", "1e300"])
def test_gains_the_design_cannot_evaluate_are_422_naming_the_field(
    rig: Rig, method: str, value: float
) -> None:
    """Bug: a gain of 1e308 raised LinAlgError in the design: 500 on PUT gains and on preview."""
    path = "/axes/pan/gains" if method == "PUT" else "/axes/pan/gains/preview"
    before = rig.client.get(f"{API}/axes/pan/gains", headers=rig.h("viewer")).json()["gains"]
    body = send(rig, "engineer", method, path, f'{{"gains": {{"kp_v_per_rad": {value!r}}}}}')
    if body.status_code == 200:  # a preview of a set the design can evaluate (and would refuse)
        assert method == "POST" and body.json()["margins"]["acceptable"] is False
    else:
        out = assert_json_error(body, 422)
        assert "kp_v_per_rad" in out["detail"]
    assert rig.client.get(f"{API}/axes/pan/gains", headers=rig.h("viewer")).json()["gains"] == before


def test_unknown_paths_and_methods_answer_in_the_json_shape(rig: Rig) -> None:
    assert assert_json_error(rig.client.get(f"{API}/no-such-thing", headers=rig.h("viewer")), 404)["error"]
    r = rig.client.request("PATCH", f"{API}/pointing", headers=rig.h("operator"))
    assert assert_json_error(r, 405)["error"] == "MethodNotAllowed"


def test_malformed_json_is_422_in_the_json_shape(rig: Rig) -> None:
    r = send(rig, "operator", "PUT", "/pointing", '{"pan_deg": 1, ')
    assert assert_json_error(r, 422)["error"] == "ValidationError"


@pytest.fixture(scope="module")
def lenient(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    """A service whose test client reports server errors as responses (as a real client sees them)."""
    yield from make_rig(tmp_path_factory.mktemp("lenient"), raise_server_exceptions=False)


def test_an_unexpected_error_is_a_json_500_and_logged(
    lenient: Rig, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """Bug: an unhandled exception came back as plain text "Internal Server Error"."""
    db = lenient.client.app.state.db  # type: ignore[attr-defined]

    def broken() -> list[dict[str, object]]:
        raise KeyError("a bug, not an input")

    monkeypatch.setattr(db, "list_presets", broken)
    r = lenient.client.get(f"{API}/presets", headers=lenient.h("viewer"))
    out = assert_json_error(r, 500)
    assert out == {"detail": "internal error", "error": "KeyError"}
    assert "a bug, not an input" not in r.text
    assert any("unhandled error on GET /api/v1/presets" in rec.message for rec in caplog.records)


def test_settings_file_example_names_every_limit(tmp_path: Path) -> None:
    from app.settings import read_config_file

    example = Path(__file__).resolve().parents[2] / "deploy" / "console.example.toml"
    names = set(read_config_file(example))
    assert {
        "max_body_bytes",
        "max_upload_bytes",
        "max_measurement_rows",
        "heavy_per_key",
        "bad_key_limit",
    } <= names
