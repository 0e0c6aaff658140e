"""`python -m dynamics list|show`."""

from dynamics.__main__ import main


def test_list_names_every_model(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out.split()
    assert {"two_link_arm", "rolling_disk", "bead_on_rotating_rod"} <= set(out)


def test_show_prints_equations_and_latex(capsys):
    assert main(["show", "bead_on_rotating_rod"]) == 0
    text = capsys.readouterr().out
    assert "coordinates r" in text and "reaction_phi" in text
    assert main(["show", "bead_on_rotating_rod", "--latex"]) == 0
    assert r"\sin{\left(\Omega t \right)}" in capsys.readouterr().out


def test_show_unknown_model_is_an_error(capsys):
    assert main(["show", "rolling_disc"]) == 2
    assert "Did you mean 'rolling_disk'" in capsys.readouterr().err
