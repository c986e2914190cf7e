import pytest

from drake_uav.vehicles.fixed_wing import aerosonde
from drake_uav.vehicles.loading import load_fixed_wing


def test_catalog_names_load():
    assert load_fixed_wing("aerosonde") == aerosonde()
    assert load_fixed_wing("unatrap").name == "unatrap"


def test_toml_overrides_a_catalog_base(tmp_path):
    path = tmp_path / "heavy.toml"
    path.write_text('base = "aerosonde"\nname = "heavy"\nmass = 15.0\n'
                    "[derivatives]\nCD_0 = 0.05\n[propulsion]\nk_motor = 70.0\n")
    params = load_fixed_wing(path)
    assert params.mass == 15.0 and params.name == "heavy"
    assert params.derivatives["CD_0"] == 0.05
    assert params.derivatives["CL_alpha"] == aerosonde().derivatives["CL_alpha"]
    assert params.propulsion.k_motor == 70.0


@pytest.mark.parametrize(
    "text, message",
    [
        ('base = "aerosonde"\nwingspan = 3.0\n', "wingspan"),
        ('base = "aerosonde"\nmass = -2.0\n', "mass"),
        ('base = "aerosonde"\n[derivatives]\nCL_flutter = 1.0\n', "CL_flutter"),
        ('base = "cessna"\n', "cessna"),
        ('name = "bare"\nmass = 2.0\n', "missing"),
        ("mass = = 2", "TOML"),
    ],
)
def test_bad_files_name_the_problem(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_fixed_wing(path)


def test_unknown_name_lists_the_catalog():
    with pytest.raises(ValueError, match="aerosonde"):
        load_fixed_wing("boeing")


def test_the_light_catalog_names_are_the_catalog():
    from drake_uav.vehicles import fixed_wing_catalog
    from drake_uav.vehicles.catalog_names import FIXED_WING_NAMES

    assert tuple(fixed_wing_catalog()) == FIXED_WING_NAMES


def test_the_vehicles_package_loads_its_modules_on_first_use():
    import subprocess
    import sys

    code = ("import sys, drake_uav.vehicles.catalog_names; "
            "print('pydrake' in sys.modules, 'drake_uav.vehicles.fixed_wing' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["False", "False"]
