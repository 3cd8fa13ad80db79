"""Our UR5e MJCF and scenes: names, published facts, loading errors."""

import mujoco
import numpy as np
import pytest

from tsrl.assets import SCENES, load_model, scene_path
from tsrl.assets.ur5e import (
    BODY_NAMES,
    HOME_Q,
    LINK_COMS_DH,
    LINK_MASSES,
    UR5E_DH,
)
from tsrl.exceptions import ModelLoadError, UnknownName, UnknownScene
from tsrl.kinematics import dh_transform, name_to_id

OBJ = mujoco.mjtObj


def test_link_masses_and_centres_of_mass_match_the_published_values():
    model = load_model("ur5e")
    for i, body in enumerate(BODY_NAMES):
        b = name_to_id(model, "body", body)
        assert model.body_mass[b] == pytest.approx(LINK_MASSES[i])
        # Body i sits at DH frame i-1 rotated by q_i; the published CoM is in DH frame i.
        T = dh_transform(*UR5E_DH[i], theta=0.0)
        com_body = T[:3, :3] @ np.array(LINK_COMS_DH[i]) + T[:3, 3]
        np.testing.assert_allclose(model.body_ipos[b], com_body, atol=1e-5)


def test_unknown_scene_lists_the_known_scenes():
    with pytest.raises(UnknownScene) as err:
        load_model("kitchen")
    message = str(err.value)
    assert "'kitchen'" in message
    for name in SCENES:
        assert name in message


def test_missing_file_is_an_unknown_scene(tmp_path):
    with pytest.raises(UnknownScene, match="known scenes"):
        load_model(tmp_path / "absent.xml")


def test_malformed_model_file_gives_a_clear_error(tmp_path):
    path = tmp_path / "broken.xml"
    path.write_text("<mujoco><worldbody><body><geom type='sphere'/></wrongtag></mujoco>")
    with pytest.raises(ModelLoadError, match=r"could not load MJCF model .*broken\.xml"):
        load_model(path)
    bad_value = tmp_path / "bad_value.xml"
    bad_value.write_text("<mujoco><worldbody><geom type='sphere' size='-1'/></worldbody></mujoco>")
    with pytest.raises(ModelLoadError, match="bad_value.xml"):
        load_model(bad_value)


def test_a_valid_model_file_loads_by_path():
    model = load_model(scene_path("reach"))
    assert model.nq == len(HOME_Q)


def test_unknown_site_lists_the_model_sites():
    model = load_model("reach")
    with pytest.raises(UnknownName, match=r"unknown site 'gripper'.*flange.*target.*tcp"):
        name_to_id(model, "site", "gripper")
