"""The data directory of a case: --data-dir, the case's data_dir, FLIGHTID_DATA, the default.

The rule is written in flightid.data.location; these tests pin its order, the most specific
setting first.
"""

from __future__ import annotations

from pathlib import Path

from flightid.data.location import DEFAULT_DATA_DIR, data_directory


def test_the_command_line_wins(tmp_path, monkeypatch):
    monkeypatch.setenv("FLIGHTID_DATA", str(tmp_path / "env"))
    assert data_directory(tmp_path, ".", override=tmp_path / "cli") == tmp_path / "cli"


def test_a_case_keeping_its_data_beside_it_is_not_redirected(tmp_path, monkeypatch):
    # the CSV walk-through: data_dir = "." must find my_flight.csv whatever FLIGHTID_DATA says
    monkeypatch.setenv("FLIGHTID_DATA", str(tmp_path / "env"))
    assert data_directory(tmp_path / "case", ".") == (tmp_path / "case").resolve()


def test_a_case_without_data_dir_reads_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv("FLIGHTID_DATA", str(tmp_path / "env"))
    assert data_directory(tmp_path, None) == tmp_path / "env"


def test_the_default_is_beside_the_checkout(tmp_path, monkeypatch):
    monkeypatch.delenv("FLIGHTID_DATA", raising=False)
    assert data_directory(tmp_path, None) == (tmp_path / Path(DEFAULT_DATA_DIR)).resolve()


def test_the_shipped_cases_give_no_data_dir():
    # so that FLIGHTID_DATA can point them at the data wherever they are; only a case whose
    # data ship in the checkout (a folder of examples/data) names its folder
    import tomllib

    examples = Path(__file__).resolve().parents[1] / "examples"
    for case in sorted((examples / "cases").glob("*.toml")):
        data = tomllib.loads(case.read_text())["data"]
        if "data_dir" in data:
            folder = (case.parent / data["data_dir"]).resolve()
            assert folder.is_dir() and folder.parent == examples / "data", case.name


# ---------------------------------------------------------------- through the case builder
# resolve_data_dir is what `flightid run` / run_case use; it once passed the default folder
# as if the case had named it, so FLIGHTID_DATA never reached the shipped cases.
_SHIPPED = Path(__file__).resolve().parents[1] / "examples" / "cases" / "hfb320_longitudinal.toml"


def test_a_shipped_case_reads_flightid_data(tmp_path, monkeypatch):
    from flightid.cases import load_case, resolve_data_dir

    monkeypatch.setenv("FLIGHTID_DATA", str(tmp_path / "env"))
    assert resolve_data_dir(load_case(_SHIPPED)) == tmp_path / "env"


def test_data_dir_on_the_command_line_beats_flightid_data(tmp_path, monkeypatch):
    from flightid.cases import load_case, resolve_data_dir

    monkeypatch.setenv("FLIGHTID_DATA", str(tmp_path / "env"))
    assert resolve_data_dir(load_case(_SHIPPED), tmp_path / "cli") == tmp_path / "cli"


def test_a_shipped_case_without_flightid_data_reads_the_default(monkeypatch):
    from flightid.cases import load_case, resolve_data_dir

    monkeypatch.delenv("FLIGHTID_DATA", raising=False)
    expected = (_SHIPPED.parent / Path(DEFAULT_DATA_DIR)).resolve()
    assert resolve_data_dir(load_case(_SHIPPED)) == expected


def test_a_case_data_dir_beats_flightid_data(tmp_path, monkeypatch):
    from flightid.cases import load_case, resolve_data_dir

    case_file = tmp_path / "beside.toml"
    case_file.write_text(_SHIPPED.read_text().replace("[data]\n", '[data]\ndata_dir = "."\n', 1))
    monkeypatch.setenv("FLIGHTID_DATA", str(tmp_path / "env"))
    assert resolve_data_dir(load_case(case_file)) == tmp_path.resolve()
