"""The package's public API: every name in ``thrombojax.__all__`` resolves, unknown ones fail."""

import pytest

import thrombojax


@pytest.mark.parametrize("name", thrombojax.__all__)
def test_every_public_name_resolves(name):
    assert getattr(thrombojax, name) is not None


def test_unknown_name_raises_attribute_error():
    with pytest.raises(AttributeError, match="no_such_thing"):
        thrombojax.no_such_thing  # noqa: B018


def test_cli_lists_only_working_subcommands(capsys):
    from thrombojax.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    for command in ("generate", "import", "info", "train", "evaluate", "rollout", "bench",
                    "export", "ensemble", "experiment"):
        assert command in out
