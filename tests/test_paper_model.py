"""The net model against the paper: Eq. 1 / Fig. 1 numbering, Eq. 2 masses, Tables 5-7."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bulletnet as bn
from bulletnet.model.net import NodeKind
from bulletnet.model.topology import thread_pairs


@pytest.mark.parametrize(("ns", "masses", "threads"), [(6, 40, 64), (11, 125, 224), (21, 445, 844)])
def test_counts(ns, masses, threads):
    # Reference: Sec. 3 / MODEL.md, Ns = 6 (Fig. 1), 11 (deployment), 21 (capture).
    model = bn.build_model(bn.load_scenario("deployment", {"net.nodes_per_side": ns}))
    assert model.node_count == masses
    assert model.thread_count == threads


def test_fig1_numbering():
    # Reference: Fig. 1 (Ns = 6), paper numbering is 1-based: thread 1 = 1-2, thread 2 = 1-7,
    # thread 10 = 5-6 is followed by 5-11; node 6 ends a row (no 6-7 thread); thread 60 = 35-36;
    # corner threads 61-64 join nodes 1, 6, 31, 36 to corner masses 37-40.
    pairs = thread_pairs(6) + 1  # back to the paper's 1-based numbering
    assert pairs[0].tolist() == [1, 2]
    assert pairs[1].tolist() == [1, 7]
    assert [6, 7] not in pairs.tolist()
    assert pairs[9].tolist() == [5, 11] and pairs[8].tolist() == [5, 6]
    assert pairs[59].tolist() == [35, 36]
    assert pairs[60:].tolist() == [[1, 37], [6, 38], [31, 39], [36, 40]]
    # Eq. 1 rule, checked independently on every inner pair
    ns = 6
    for i, j in pairs[:60]:
        assert (j == i + 1 and i % ns != 0) or j == i + ns


def test_masses_eq2():
    # Reference: Eq. 2, m_i = sum of half the adjacent thread masses, m_p = rho pi r^2 l_0.
    s = bn.load_scenario("deployment")
    model = bn.build_model(s)
    m_thread = 1390 * math.pi * 0.001**2 * 0.5
    m_corner_thread = 1390 * math.pi * 0.002**2 * 0.70710678
    kind = model.kind
    assert np.allclose(model.mass[kind == NodeKind.INNER], 4 * m_thread / 2, rtol=1e-14)
    assert np.allclose(model.mass[kind == NodeKind.EDGE], 3 * m_thread / 2, rtol=1e-14)
    assert np.allclose(model.mass[kind == NodeKind.CORNER],
                       (2 * m_thread + m_corner_thread) / 2, rtol=1e-14)
    assert np.allclose(model.mass[kind == NodeKind.CORNER_MASS],
                       0.5 + m_corner_thread / 2, rtol=1e-14)


def _printed(value: float, printed: str) -> bool:
    """True if ``value`` rounds to the table's printed number (within half its last digit)."""
    decimals = len(printed.split(".")[1]) if "." in printed else 0
    return abs(value - float(printed)) <= 0.5 * 10.0**-decimals * (1 + 1e-9)


TABLE7 = {  # Reference: Table 7 (capture threads), as printed
    "inner": {"k_a": "54977.9", "c_a": "115.922", "k_t": "0.01031", "c_t": "0.00013",
              "k_b": "0.00344", "c_b": "0.00008"},
    "corner": {"k_a": "77750.5", "c_a": "163.939", "k_t": "0.01458", "c_t": "0.00019",
               "k_b": "0.00972", "c_b": "0.00022"},
}

CLASSES = ("spacecraft", "corner_mass", "corner_node", "edge_node", "inner_node")
TABLE5 = [  # Reference: Table 5, k_c [1e9 N/m], upper triangle from the diagonal
    [None, "9.712", "4.591", "4.241", "4.449"],
    ["6.867", "4.161", "3.895", "4.055"],
    ["3.295", "3.162", "3.243"],
    ["3.044", "3.116"],
    ["3.193"],
]
TABLE6 = [  # Reference: Table 6, c_c [N s/m]
    [None, "1396", "70", "53", "62"],
    ["830", "66", "50", "59"],
    ["42", "36", "39"],
    ["32", "34"],
    ["37"],
]


def test_table7_threads():
    model = bn.build_model(bn.load_scenario("capture"))
    for label, p in (("inner", 0), ("corner", model.thread_count - 1)):
        ours = {"k_a": model.axial_stiffness[p], "c_a": model.axial_damping[p],
                "k_t": model.transverse_stiffness[p], "c_t": model.transverse_damping[p],
                "k_b": model.bending_stiffness[p], "c_b": model.bending_damping[p]}
        for key, printed in TABLE7[label].items():
            assert _printed(ours[key], printed), (label, key, ours[key], printed)


def test_tables5_6_contact():
    s = bn.load_scenario("capture")
    table = bn.contact_table(s, bn.build_model(s))
    checked = 0
    for a_index, a in enumerate(CLASSES):
        for offset, b in enumerate(CLASSES[a_index:]):
            k_printed, c_printed = TABLE5[a_index][offset], TABLE6[a_index][offset]
            if k_printed is None:
                continue
            k, c = table[(a, b)]
            assert _printed(k / 1e9, k_printed), (a, b, k / 1e9, k_printed)
            assert _printed(c, c_printed), (a, b, c, c_printed)
            checked += 1
    assert checked == 14
