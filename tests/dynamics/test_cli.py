"""`python -m dynamics list|show`."""

import pytest

from dynamics.__main__ import main, show


def test_list_names_every_model(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out.split()
    assert {"two_link_arm", "rolling_disk", "bead_on_rotating_rod"} <= set(out)


@pytest.mark.slow
def test_show_prints_equations_and_latex(capsys):
    assert main(["show", "bead_on_rotating_rod"]) == 0
    text = capsys.readouterr().out
    assert "coordinates r" in text and "reaction_phi" in text
    assert main(["show", "bead_on_rotating_rod", "--latex"]) == 0
    assert r"\sin{\left(\Omega t \right)}" in capsys.readouterr().out


def test_show_unknown_model_is_an_error(capsys):
    assert main(["show", "rolling_disc"]) == 2
    assert "Did you mean 'rolling_disk'" in capsys.readouterr().err


def test_cache_command_lists_compiled_models(capsys, monkeypatch, tmp_path):
    import dynamics
    from dynamics import cache

    monkeypatch.setenv("LAGRANGE_GYM_CACHE", str(tmp_path))
    monkeypatch.setattr(cache, "_loaded", {})  # forget modules loaded by earlier tests
    dynamics.get_model("bead_on_rotating_rod").compile()
    assert main(["cache"]) == 0
    assert "1 compiled models" in capsys.readouterr().out
    assert main(["cache", "--clear"]) == 0
    assert not list(tmp_path.glob("*.py"))


@pytest.mark.slow
def test_show_says_why_it_does_not_print_the_bicycles_equations():
    # simplifying 111,626 nodes for display would take hours; the command says so instead
    out = show("whipple_bicycle")
    assert "too large to simplify and print" in out and "python -m dynamics.bicycle" in out
