"""Contract of every method in ``METHODS`` (issue 12 §4), beside :mod:`test_contract`'s behaviour checks.

* every parameter (a field of the method's ``params_type``) is documented in the dataclass docstring,
  with its unit (or "(-)" / "dimensionless" for a ratio, or as a switch for a boolean / a choice);
* pinned numeric snapshots of the defaults on a small seeded simulated input (a few quaternions at fixed
  indices, tolerance 1e-9).  The snapshots are the outputs of the code at the commit that wrote them:
  they pin behaviour, they are not truth.  Regenerate them only deliberately, after a change meant to
  alter the numbers (run this file with ``CHAKAMO_PRINT_SNAPSHOTS=1`` and paste the printed table), and
  say so in the commit message.

Online = batch, two halves = one batch and numba kernel = numpy reference run for every method in
:mod:`test_contract` (``test_two_half_batches_equal_one_batch``, ``test_kernel_equals_reference``).
"""

import os
import re
from dataclasses import fields

import numpy as np
import pytest

from estimators.orientation import METHOD_INFO, METHODS, get_method, make
from estimators.simulation import ImuSpec, motions, simulate_on_grid

UNIT = re.compile(r"(\brad\b|rad/s|rad²|\bs\b|\bs,|m/s²|µT|\bHz\b|√Hz|\(-\)|dimensionless|°|\bg\b)")
SNAPSHOT_INDICES = (0, 137, 451, 799)


def _doc_entry(doc: str, name: str) -> str:
    """The docstring text of parameter ``name`` (alone or in a ``a, b, c`` group) up to the next entry."""
    match = re.search(rf"^\s*(?:[a-z_0-9]+,\s*)*{re.escape(name)}\b[^\n]*(?:\n(?!\s*[a-z_0-9]+\s*[:,(\n]).*)*",
                      doc, re.M)
    return match.group(0) if match else ""


@pytest.mark.parametrize("name", METHODS)
def test_every_parameter_documented_with_its_unit(name):
    params_type = get_method(name).params_type
    doc = params_type.__doc__ or ""
    missing, unitless = [], []
    for f in fields(params_type):
        entry = _doc_entry(doc, f.name)
        default = getattr(params_type(), f.name)
        if not entry:
            missing.append(f.name)
        elif not isinstance(default, (bool, str)) and not UNIT.search(entry):
            unitless.append(f.name)
    assert not missing, f"{params_type.__name__}: not in the docstring: {missing}"
    assert not unitless, f"{params_type.__name__}: documented without a unit: {unitless}"


@pytest.fixture(scope="module")
def snapshot_input():
    g = simulate_on_grid(motions.rotations(10.0, seed=11), ImuSpec(), fs_hz=100.0, seed=11)
    return g.acc[:800], g.gyr[:800], g.mag[:800]


CASES = [(info.name, mode) for info in METHOD_INFO for mode, ok in (("9d", info.has_9d), ("6d", info.has_6d)) if ok]

# generated at the commit that added this file (see module docstring); rows at SNAPSHOT_INDICES
SNAPSHOTS: dict[tuple[str, str], list[list[float]]] = {
    ('chakamo', '9d'): [
        [0.9068791114573344, -0.012316098050614318, -0.0002567977336535555, 0.4212107845082883],
        [0.9049317604202013, -0.005154360413897197, -0.00548886551741688, 0.42549008673158417],
        [0.9050860865684528, -0.003799465692584781, -0.005538827262615208, 0.42517533013241604],
        [0.9053220005348955, -0.0010887476812130121, -0.007847113378446945, 0.42465199020799027],
    ],
    ('chakamo', '6d'): [
        [0.9999241205059182, -0.011278075990361727, 0.004955524011036528, -3.184647132801568e-05],
        [0.9999606427542257, -0.006986906820800348, -0.0028068147466662765, 0.0046923199604264705],
        [0.9999680164135087, -0.0057791394824351595, -0.0034228780049488077, 0.004341843276604523],
        [0.9999615197299874, -0.004293037597080892, -0.0066582571351359015, 0.003767824227126245],
    ],
    ('guo', '9d'): [
        [0.9141939327263435, -0.011496734887565583, 8.382589375442535e-05, 0.405113899325222],
        [0.9121596393038015, 0.0006604727670359409, -0.00844493551794082, 0.40974753112737683],
        [0.9052033421594655, -0.007622829350893132, -0.007599305826637005, 0.4248423853230444],
        [0.9017385765459428, -0.0016467957804604369, -0.00254215272415209, 0.43227117078528554],
    ],
    ('guo', '6d'): [
        [0.999933833660782, -0.010486314048495633, 0.004729213271494398, -7.743426682208968e-06],
        [0.9999371850406008, -0.0028144340698484753, -0.008004741619912202, 0.007323185477944997],
        [0.9999479330667939, -0.008282060283594697, -0.0021457332601206355, 0.00556187573416304],
        [0.999950729377659, -0.005725494585855598, -0.00455471133851092, 0.006709108246095894],
    ],
    ('madgwick', '9d'): [
        [0.9143287294442819, -0.011207436249439418, 0.000565277928677188, 0.4048173024296063],
        [0.9127033203310564, -0.0027582968626037162, -0.0059365493320877784, 0.40857043240683777],
        [0.8744559285520637, -0.004252354496721111, -0.013691328040006525, 0.4848930748504079],
        [0.8848535220113211, -0.008783133512799374, -0.03146526453363104, 0.4647225390248311],
    ],
    ('madgwick', '6d'): [
        [0.9999373381696323, -0.010297401501563963, 0.004391258157393745, -1.0408701467329585e-05],
        [0.9999530800879927, -0.0045784804019601, -0.004112197549576011, 0.0074809739378416664],
        [0.9999785979589998, -0.0049576821135907416, -0.004022915310802529, -0.001428693254541209],
        [0.9999673227132281, -0.0049940646400791645, -0.003487372990477615, -0.0053151720324884875],
    ],
    ('valenti_cf', '9d'): [
        [0.9145147386462853, -0.011974593224611474, 0.0004418607363482933, 0.40437508166912484],
        [0.9115320750399543, 0.000770136538045501, -0.008466898613696436, 0.41114108854617487],
        [0.8897200485016431, 0.018886273677125268, -0.015975571723903466, 0.45583585320696407],
        [0.8885162373961464, 0.031815193896734456, -0.025929773431401994, 0.4570058382236534],
    ],
    ('valenti_cf', '6d'): [
        [0.9999282043540477, -0.010773018710946419, 0.005246731521512759, -3.672142290734604e-06],
        [0.9999360651017939, -0.0027192036616682305, -0.008055272426691563, 0.007455482970214371],
        [0.9996930963563306, 0.00949350057059877, -0.0228425846223436, -0.0013427107579173916],
        [0.9991426880922843, 0.016228007137002322, -0.03769895883511888, -0.005415636512327002],
    ],
    ('valenti_kf', '9d'): [
        [0.9131631500431503, -0.006646226875128939, -0.0014248235106570006, 0.4075375552627741],
        [0.911426650158013, 0.002461506692532872, -0.009733165228435313, 0.41134008783630793],
        [0.9001226569575299, 0.016127505149788456, -0.010851779093008275, 0.43520264808463316],
        [0.8952533285663982, 0.012657374927943709, -0.013151271991458262, 0.4451834594812852],
    ],
    ('valenti_kf', '6d'): [
        [0.9999679656159042, -0.008000448923073784, 0.00024229346845010461, -4.3045257252635385e-05],
        [0.999922547168947, -0.001656079276709412, -0.009837271561430744, 0.007442120183172611],
        [0.9999197906639359, 0.0009201614106506902, -0.012569676325447242, -0.001252508938992815],
        [0.9998162203166592, 0.0028381525472206616, -0.018230157872875772, -0.005208821916563255],
    ],
}


@pytest.mark.parametrize("name, mode", CASES)
def test_default_snapshot(name, mode, snapshot_input):
    acc, gyr, mag = snapshot_input
    q = make(name).estimate(acc, gyr, mag if mode == "9d" else None, fs_hz=100.0).orientation_
    got = q[list(SNAPSHOT_INDICES)]
    if os.environ.get("CHAKAMO_PRINT_SNAPSHOTS"):
        print(f"    ({name!r}, {mode!r}): {got.tolist()!r},")
    assert (name, mode) in SNAPSHOTS, f"no snapshot for {name} {mode}: generate it deliberately (module docstring)"
    np.testing.assert_allclose(got, np.array(SNAPSHOTS[(name, mode)]), atol=1e-9, rtol=0)
