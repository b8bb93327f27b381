"""The floor plan fitted onto the robot's map from matched spots, over real sockets (issue 29):
the fit recovers a known scale, rotation and translation; applied, the plan is drawn under the
map on every screen (its image served by its digest), kept across a restart, and gone with a new
map of the room; a bad request changes nothing."""

from __future__ import annotations

import io
import math

import numpy as np
from PIL import Image

from serveur.maps.align import Similarity
from serveur.maps.mapfiles import map_files
from tests.conftest import Client, restaurant
from tests.test_site_map import owner, upload, walled_demo

# A robot's map frame vs the floor plan's pixels: 3 cm per pixel, turned 15 degrees, shifted
# (the spots below fall on an 820 x 600 pixel plan).
TRUE = Similarity(0.03, math.radians(-15), -4.0, 18.0)
#: Spots on the robot's map (m): the room's corners and a pillar, as the owner would pick them.
SPOTS = [(-0.2, -0.3), (15.8, -0.1), (15.9, 11.6), (-0.1, 11.8), (8.0, 6.0)]


def plan_pixel(x: float, y: float) -> list[float]:
    """Where the map's spot (x, y) is on the plan: (column, row), rows counted downwards."""
    c, minus_r = TRUE.inverse().apply(x, y)
    return [round(c, 3), round(-minus_r, 3)]


def pairs(spots: list[tuple[float, float]] = SPOTS) -> list[dict[str, list[float]]]:
    return [{"plan": plan_pixel(x, y), "map": [x, y]} for x, y in spots]


def png() -> bytes:
    out = io.BytesIO()
    Image.fromarray(np.full((40, 60), 200, dtype=np.uint8)).save(out, format="PNG")
    return out.getvalue()


async def map_now(c: Client) -> dict[str, object]:
    return dict((await c.ok("data", topics=["map"]))["data"]["map"])


async def test_the_floor_plan_is_fitted_and_drawn_under_the_map(tmp_path: object) -> None:
    async with restaurant(tmp_path, time_scale=10.0) as r:  # type: ignore[arg-type]
        password = r.app.first_owner_password or ""
        c = await owner(r, password)
        got = (await c.ok("site", action="align_map", points=pairs()))["alignment"]
        assert math.isclose(got["scale"], TRUE.scale, rel_tol=1e-4)
        assert math.isclose(got["rotation"], TRUE.rotation, abs_tol=1e-4)
        assert math.isclose(got["tx"], TRUE.tx, abs_tol=1e-3)
        assert math.isclose(got["ty"], TRUE.ty, abs_tol=1e-3)
        assert got["rms"] < 0.001 and len(got["residuals"]) == len(SPOTS)
        assert "backdrop" not in await map_now(c)  # a fit alone changes nothing

        # One spot mis-tapped by 40 px on the plan: its residual says which.
        bad = pairs()
        bad[2]["plan"] = [bad[2]["plan"][0] + 40, bad[2]["plan"][1]]
        off = (await c.ok("site", action="align_map", points=bad))["alignment"]
        worst = max(range(len(SPOTS)), key=lambda i: off["residuals"][i])
        assert worst == 2 and off["rms"] > 0.2

        image = png()
        plan = await upload(c, "plan", "plan.png", image)
        await c.ok("site", action="align_map", points=pairs(), upload=plan, apply=True)
        drawn = await map_now(c)
        backdrop = drawn["backdrop"]
        assert isinstance(backdrop, dict)
        assert math.isclose(backdrop["scale"], TRUE.scale, rel_tol=1e-4)
        status, body, kind = await r.get(backdrop["url"])
        assert (status, body, kind) == (200, image, "image/png")
        wrong = backdrop["url"][:-4] + "0000"
        assert (await r.get(wrong))[0] == 404

        await r.restart_server()  # kept in the database
        c = await owner(r, password)
        assert (await map_now(c))["backdrop"] == backdrop

        # A new map of the room: another frame, the fit no longer holds, the plan goes.
        text, pgm = map_files(walled_demo(), "room")
        y = await upload(c, "map_yaml", "room.yaml", text)
        i = await upload(c, "map_image", "room.pgm", pgm)
        await c.ok("site", action="set_map", yaml=y, image=i)
        assert "backdrop" not in await map_now(c)
        assert (await r.get(backdrop["url"]))[0] == 404


async def test_bad_fits_are_refused_and_change_nothing(tmp_path: object) -> None:
    async with restaurant(tmp_path, time_scale=10.0) as r:  # type: ignore[arg-type]
        c = await owner(r, r.app.first_owner_password or "")
        await c.error("site", "invalid_field", action="align_map", points=pairs()[:1])
        bunched = pairs([(5.0, 5.0), (5.1, 5.0), (5.0, 5.1)])
        err = await c.error("site", "invalid_field", action="align_map", points=bunched)
        assert "too close together" in err["message"]
        mirrored = [{"plan": [820 - q["plan"][0], q["plan"][1]], "map": q["map"]} for q in pairs()]
        err = await c.error("site", "invalid_field", action="align_map", points=mirrored)
        assert err["details"]["reason"] == "mismatch", err
        err = await c.error("site", "invalid_field", action="align_map", points=pairs(), apply=True)
        assert err["details"]["field"] == "upload"
        text = await upload(c, "plan", "plan.png", b"not a picture at all")
        err = await c.error(
            "site", "invalid_field", action="align_map", points=pairs(), upload=text, apply=True
        )
        assert "PNG or JPEG" in err["message"]
        assert "backdrop" not in await map_now(c)
        assert await r.app.store.site_backdrop.get() is None
