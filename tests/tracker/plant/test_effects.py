"""What an effect's own file says about it: when fitted values are too small to be a missing effect."""


def test_stiction_within_ten_percent_of_coulomb_is_negligible_and_above_it_is_not() -> None:
    from tracker.plant.effects import get_effect

    check = get_effect("stiction").negligible
    assert check is not None
    fc = 0.06
    assert check({"coulomb.torque": fc, "stiction.static_torque": 1.05 * fc}) is not None
    assert "5.0 %" in str(check({"coulomb.torque": fc, "stiction.static_torque": 1.05 * fc}))
    assert check({"coulomb.torque": fc, "stiction.static_torque": 1.5 * fc}) is None
