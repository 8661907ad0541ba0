"""Plugins: a class another installed package declares by an entry point (hybrid_sysid.objectives, .networks,
.baselines) is named by its class path in ``_target_``; a name no installed package declares is refused before
anything is imported; a plugin whose import raises, or whose class lacks a member of its interface, is one line
naming the entry point; a run made with a plugin names the package to install where it is missing.

Each package here is installed the way pip leaves one: its modules and a ``<name>.dist-info`` with METADATA and
entry_points.txt, in a folder on sys.path for the test alone. tests/cli/test_plugin_sweep.py installs the example
package (tests/plugins/example) with pip and sweeps with it from the command line."""

import sys
import textwrap

import pytest

from hybrid_sysid.config.targets import build, check_saved, known_class, plugin_fields
from hybrid_sysid.core.checks import ConfigError

OBJECTIVE = """
import torch
from torch import nn


class AbsObjective(nn.Module):
    uses_labels = True
    fir = None
    outside_fir = None
    monitor = "val/rel_dev"

    def __init__(self, scale: float = 1.0):
        super().__init__()
        self.scale = scale

    def forward(self, pred, batch):
        return self.scale * (pred - batch["params"]).abs().mean()
"""
LACKING = """
class NoBoundsNet:  # a network without output_bounds
    prior_arguments = ()

    @staticmethod
    def window_bounds(**arguments):
        return 1, None

    def __call__(self, signals):
        return signals
"""
INCOMPLETE_BASELINE = """
class HalfBaseline:  # estimates, but cannot be evaluated on a split nor check its lengths
    fit_seconds = 0.0

    def estimate(self, seat, body, dt, measurement, window, windows):
        return None
"""


@pytest.fixture
def install(tmp_path, monkeypatch):
    """``install(dist, modules, entry_points)``: a package ``dist`` with ``modules`` ({name: source}) and
    ``entry_points`` ({group: {name: value}}) installed in a folder on sys.path; gone after the test, with every
    module it loaded."""
    site = tmp_path / "site"
    names = []

    def _install(dist, modules, entry_points):
        info = site / f"{dist.replace('-', '_')}-0.1.0.dist-info"
        info.mkdir(parents=True)
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1.0\n")
        lines = [
            f"[{group}]\n" + "".join(f"{n} = {v}\n" for n, v in eps.items()) for group, eps in entry_points.items()
        ]
        (info / "entry_points.txt").write_text("\n".join(lines))
        for name, source in modules.items():
            (site / f"{name}.py").write_text(textwrap.dedent(source))
            names.append(name)
        monkeypatch.syspath_prepend(str(site))

    yield _install
    for name in names:
        sys.modules.pop(name, None)


def one_line(err, key, target, *words):
    message = str(err.value)
    assert message.startswith(f"{key}._target_ = '{target}' is not allowed: ") and "\n" not in message, message
    assert all(w in message for w in words), message


def test_a_declared_class_is_named_by_its_class_path_and_built(install):
    install("abs-objective", {"abs_obj": OBJECTIVE}, {"hybrid_sysid.objectives": {"abs": "abs_obj:AbsObjective"}})
    objective = build({"_target_": "abs_obj.AbsObjective", "scale": 2.0}, "objective")
    assert type(objective).__name__ == "AbsObjective" and type(objective).__module__ == "abs_obj"
    torch = pytest.importorskip("torch")
    pred, true = torch.tensor([[1.0, 2.0]]), torch.tensor([[2.0, 4.0]])
    assert objective(pred, {"params": true}).item() == pytest.approx(2.0 * (1 + 2) / 2)
    # its arguments are checked like the package's own classes'
    with pytest.raises(ConfigError, match=r"^objective\.depth = 3 is not allowed: not an argument of AbsObjective"):
        build({"_target_": "abs_obj.AbsObjective", "depth": 3}, "objective")


def test_the_value_module_dot_class_is_read_as_module_colon_class(install):
    install("abs-objective", {"abs_obj": OBJECTIVE}, {"hybrid_sysid.objectives": {"abs": "abs_obj.AbsObjective"}})
    assert known_class("abs_obj.AbsObjective", "objective").__name__ == "AbsObjective"


def test_a_class_no_installed_package_declares_is_refused_before_its_module_is_imported(install, tmp_path):
    marker = tmp_path / "imported"
    source = f"open({str(marker)!r}, 'w').close()\n" + OBJECTIVE
    # the module is importable, and declared, but as a network: the key objective does not take it
    install("abs-objective", {"abs_obj": source}, {"hybrid_sysid.networks": {"abs": "abs_obj:AbsObjective"}})
    with pytest.raises(ConfigError) as err:
        known_class("abs_obj.AbsObjective", "objective")
    one_line(
        err, "objective", "abs_obj.AbsObjective", "none declares it in the entry point group hybrid_sysid.objectives"
    )
    assert not marker.exists() and "abs_obj" not in sys.modules


def test_a_plugin_whose_import_raises_is_one_line_naming_its_entry_point(install):
    broken = "raise RuntimeError('no licence server\\nat  port 27000')\n"
    install("broken-plugin", {"broken_obj": broken}, {"hybrid_sysid.objectives": {"broken": "broken_obj:Objective"}})
    with pytest.raises(ConfigError) as err:
        known_class("broken_obj.Objective", "objective")
    words = ("entry point hybrid_sysid.objectives:broken of broken-plugin", "RuntimeError: no licence server at port")
    one_line(err, "objective", "broken_obj.Objective", *words)


def test_an_entry_point_naming_nothing_is_one_line(install):
    install("abs-objective", {"abs_obj": OBJECTIVE}, {"hybrid_sysid.objectives": {"typo": "abs_obj:AbsObjectiv"}})
    with pytest.raises(ConfigError) as err:
        known_class("abs_obj.AbsObjectiv", "objective")
    one_line(err, "objective", "abs_obj.AbsObjectiv", "hybrid_sysid.objectives:typo", "AttributeError")


@pytest.mark.parametrize(
    "key, group, module, cls, words",
    [
        ("model.net", "hybrid_sysid.networks", LACKING, "NoBoundsNet", "a class with output_bounds (Network"),
        (
            "baseline",
            "hybrid_sysid.baselines",
            INCOMPLETE_BASELINE,
            "HalfBaseline",
            "a class with predict_split, check_lengths (Baseline",
        ),
    ],
)
def test_a_plugin_class_lacking_a_member_is_one_line_naming_it(install, key, group, module, cls, words):
    install("lab", {"lab_mod": module}, {group: {"mine": f"lab_mod:{cls}"}})
    with pytest.raises(ConfigError) as err:
        known_class(f"lab_mod.{cls}", key)
    one_line(err, key, f"lab_mod.{cls}", words, f"entry point {group}:mine of lab")


def test_a_run_records_its_plugin_and_names_the_package_where_it_is_missing(install, make_cfg):
    cfg = make_cfg("objective._target_=abs_obj.AbsObjective", "~objective.p_scale")
    assert plugin_fields(cfg) == {}  # not installed yet: nothing to record, and refused
    with pytest.raises(ConfigError) as err:
        check_saved(cfg, None)
    one_line(err, "objective", "abs_obj.AbsObjective", "none declares it")

    install("abs-objective", {"abs_obj": OBJECTIVE}, {"hybrid_sysid.objectives": {"abs": "abs_obj:AbsObjective"}})
    record = plugin_fields(cfg)
    assert record == {
        "plugins": {
            "objective": {
                "class": "abs_obj.AbsObjective",
                "entry_point": "hybrid_sysid.objectives:abs",
                "package": "abs-objective",
                "version": "0.1.0",
            }
        }
    }
    check_saved(cfg, record)  # installed: the run opens
    assert plugin_fields(make_cfg()) == {}  # the package's own classes are no plugins


def test_a_received_run_made_with_a_plugin_names_the_package_to_install(make_cfg):
    """What a run's record says it was made with names the package; a record cannot make a class allowed."""
    cfg = make_cfg("objective._target_=abs_obj.AbsObjective", "~objective.p_scale")
    made = {"class": "abs_obj.AbsObjective", "entry_point": "hybrid_sysid.objectives:abs", "package": "abs-objective"}
    with pytest.raises(ConfigError) as err:
        check_saved(cfg, {"plugins": {"objective": {**made, "version": "0.1.0"}}})
    words = ("entry point hybrid_sysid.objectives:abs of the package abs-objective 0.1.0", "pip install abs-objective")
    one_line(err, "objective", "abs_obj.AbsObjective", *words)
    # a record naming another class (or none) says only where such a class is declared
    for record in ({"plugins": {"objective": {**made, "class": "abs_obj.Other"}}}, {"plugins": "garbage"}, None):
        with pytest.raises(ConfigError, match="none declares it in the entry point group hybrid_sysid.objectives"):
            check_saved(cfg, record)


def test_a_plugin_whose_import_raises_stops_the_command_in_one_line_writing_nothing(install, tmp_path, cli_in_process):
    from hybrid_sysid.cli.train import main

    broken = "raise ImportError('needs mylab-extras')\n"
    install("broken-plugin", {"broken_obj": broken}, {"hybrid_sysid.objectives": {"broken": "broken_obj:Objective"}})
    (tmp_path / "work").mkdir()
    args = ["objective._target_=broken_obj.Objective", "~objective.p_scale", "data=tiny", "trainer=debug"]
    code, out, err = cli_in_process(main, *args, cwd=tmp_path / "work", env={"HYBRID_SYSID_CACHE": tmp_path / "c"})
    assert code == 2, err[-2000:]
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: objective._target_ = 'broken_obj.Objective'"), err
    assert "hybrid_sysid.objectives:broken of broken-plugin" in lines[0] and "needs mylab-extras" in lines[0]
    assert list((tmp_path / "work").iterdir()) == [] and not (tmp_path / "c").exists()


@pytest.mark.parametrize(
    "member, shown",
    [
        ("fir = 42", "objective.fir = 42 is not allowed: None, or the band-pass's taps"),
        ("fir = 'abc'", "objective.fir = 'abc' is not allowed: None, or the band-pass's taps"),
        ("outside_fir = [float('nan')]", "objective.outside_fir = [nan] is not allowed"),
        ("uses_labels = 'yes'", "objective.uses_labels = 'yes' is not allowed: True or False"),
        ("monitor = 'val/bogus'", "objective.monitor = 'val/bogus' is not allowed: one of"),
    ],
)
def test_a_plugin_objectives_member_of_the_wrong_type_is_one_line_naming_it(
    install, cli_in_process, tmp_path, member, shown
):
    """The command with a plugin objective whose member has the wrong value: one line naming the member's key,
    exit 2, nothing made (a fir of 42 once failed deep in the data module)."""
    from hybrid_sysid.cli.train import main

    source = OBJECTIVE.replace('    monitor = "val/rel_dev"\n', f'    monitor = "val/rel_dev"\n    {member}\n', 1)
    assert member in source
    install("abs-objective", {"abs_obj": source}, {"hybrid_sysid.objectives": {"abs": "abs_obj:AbsObjective"}})
    args = ["data=tiny", "trainer=debug", "trainer.max_steps=2", "hydra.run.dir=run"]
    args += ["objective._target_=abs_obj.AbsObjective", "~objective.p_scale"]
    code, out, err = cli_in_process(main, *args, cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err[-2000:]
    assert err.startswith(f"error: {shown}"), err
    assert not (tmp_path / "run").exists() and not (tmp_path / "outputs").exists()
