"""Hertz-based contact stiffness and damping of every contact pair (Eq. 7-11, Tables 5-6)."""

from __future__ import annotations

import math

from .net import NetModel, NodeKind
from .scenario import Material, Scenario

BODY_CLASSES = ("spacecraft", "corner_mass", "corner_node", "edge_node", "inner_node")
"""Contact body classes in the order of Tables 5-6."""

_KIND_OF_CLASS = {"corner_mass": NodeKind.CORNER_MASS, "corner_node": NodeKind.CORNER,
                  "edge_node": NodeKind.EDGE, "inner_node": NodeKind.INNER}


def compliance(material: Material) -> float:
    """h = (1 - nu^2) / (pi E) [1/Pa] (Eq. 8)."""
    return (1.0 - material.poisson_ratio**2) / (math.pi * material.young_modulus)


def hertz_stiffness(radius: float, h1: float, h2: float) -> float:
    """k_c = 4 sqrt(r) / (3 pi (h1 + h2)) [N/m] (Eq. 7; Eq. 9 with r = r_eq of Eq. 10)."""
    return 4.0 * math.sqrt(radius) / (3.0 * math.pi * (h1 + h2))


def equivalent(a: float, b: float) -> float:
    """a b / (a + b): the equivalent radius (Eq. 10) or reduced mass (Eq. 11)."""
    return a * b / (a + b)


def contact_damping(stiffness: float, mass: float, ratio: float) -> float:
    """c_c = 2 xi sqrt(k_c m_c) [N s/m] (Sec. 3.3)."""
    return 2.0 * ratio * math.sqrt(stiffness * mass)


def contact_table(s: Scenario, model: NetModel) -> dict[tuple[str, str], tuple[float, float]]:
    """(k_c [N/m], c_c [N s/m]) for every unordered pair of :data:`BODY_CLASSES` present in the
    net. The spacecraft is a plane locally (sphere-plane); node pairs are sphere-sphere."""
    props = {}  # class -> (radius [m], mass [kg], compliance [1/Pa])
    for name, kind in _KIND_OF_CLASS.items():
        nodes = (model.kind == kind).nonzero()[0]
        if nodes.size:
            material = s.materials.corner_mass if kind == NodeKind.CORNER_MASS else s.materials.net
            props[name] = (model.radius[nodes[0]], model.mass[nodes[0]], compliance(material))
    h_sc = compliance(s.materials.debris)
    ratio = s.contact.damping_ratio
    table = {}
    for a_index, a in enumerate(BODY_CLASSES):
        for b in BODY_CLASSES[a_index:]:
            if a == "spacecraft":
                if b == "spacecraft" or b not in props:
                    continue
                r, m, h = props[b]
                k = hertz_stiffness(r, h_sc, h)
            else:
                if a not in props or b not in props:
                    continue
                (ra, ma, ha), (rb, mb, hb) = props[a], props[b]
                k = hertz_stiffness(equivalent(ra, rb), ha, hb)
                m = equivalent(ma, mb)
            table[(a, b)] = (k, contact_damping(k, m, ratio))
    return table
