"""Two-node Timoshenko beam element with interdependent interpolation (Friedman & Kosmatka 1993).

Degrees of freedom per node: lateral displacement ``u`` (m) and cross-section
rotation ``θ`` (rad; ``θ = du/dz`` in the Euler–Bernoulli limit), element
vector ``[u1, θ1, u2, θ2]``.

With ``ξ = z/L`` and ``Φ = 12 EI / (κGA L²)`` the interpolation functions
that solve the static homogeneous Timoshenko equations exactly are
(Friedman, Z. and Kosmatka, J. B., "An improved two-node Timoshenko beam
finite element", Computers & Structures 47(3), 473–481, 1993)::

    N_u = 1/(1+Φ) [ 2ξ³−3ξ²−Φξ+1+Φ,  L(ξ³−(2+Φ/2)ξ²+(1+Φ/2)ξ),
                   −2ξ³+3ξ²+Φξ,      L(ξ³−(1−Φ/2)ξ²−(Φ/2)ξ) ]
    N_θ = 1/(1+Φ) [ 6(ξ²−ξ)/L,  3ξ²−(4+Φ)ξ+1+Φ,  −6(ξ²−ξ)/L,  3ξ²−(2−Φ)ξ ]

The stiffness is the closed form (equal to
``∫ EI N_θ'ᵀN_θ' + κGA (N_u'−N_θ)ᵀ(N_u'−N_θ) dz``, checked in the tests)::

    K = EI / ((1+Φ) L³) [[12, 6L, −12, 6L], [6L, (4+Φ)L², −6L, (2−Φ)L²],
                         [−12, −6L, 12, −6L], [6L, (2−Φ)L², −6L, (4+Φ)L²]]

and the consistent mass ``∫ ρA N_uᵀN_u + ρI N_θᵀN_θ dz`` is integrated
exactly by 5-point Gauss–Legendre quadrature (the integrands are polynomials
of degree 6).  Complex EI and κGA (structural damping) give the complex
stiffness directly; the mass uses the real part of Φ.
"""

from __future__ import annotations

import numpy as np

__all__ = ["shape_functions", "element_stiffness", "element_mass", "element_stiffness_quadrature"]

_GX, _GW = np.polynomial.legendre.leggauss(5)
_XI = 0.5 * (_GX + 1.0)
_W = 0.5 * _GW


def shape_functions(xi, length: float, phi: float):
    """Interpolation functions and their z-derivatives.

    Parameters
    ----------
    xi : (n,) float
        Local coordinate z/L in [0, 1].
    length : float, m
    phi : float
        Shear parameter Φ = 12 EI / (κGA L²).

    Returns
    -------
    Nu, Nt, dNu, dNt : (n, 4) float
        Displacement and rotation functions and their derivatives d/dz.
    """
    x = np.asarray(xi, dtype=float)
    L, P = length, phi
    c = 1.0 / (1.0 + P)
    Nu = c * np.column_stack([
        2 * x**3 - 3 * x**2 - P * x + 1 + P,
        L * (x**3 - (2 + P / 2) * x**2 + (1 + P / 2) * x),
        -2 * x**3 + 3 * x**2 + P * x,
        L * (x**3 - (1 - P / 2) * x**2 - (P / 2) * x),
    ])
    Nt = c * np.column_stack([
        6 * (x**2 - x) / L,
        3 * x**2 - (4 + P) * x + 1 + P,
        -6 * (x**2 - x) / L,
        3 * x**2 - (2 - P) * x,
    ])
    dNu = c / L * np.column_stack([
        6 * x**2 - 6 * x - P,
        L * (3 * x**2 - (4 + P) * x + 1 + P / 2),
        -6 * x**2 + 6 * x + P,
        L * (3 * x**2 - (2 - P) * x - P / 2),
    ])
    dNt = c / L * np.column_stack([
        (12 * x - 6) / L,
        6 * x - (4 + P),
        -(12 * x - 6) / L,
        6 * x - (2 - P),
    ])
    return Nu, Nt, dNu, dNt


def element_stiffness(EI: complex, kGA: complex, length: float) -> np.ndarray:
    """Closed-form Timoshenko element stiffness.

    Parameters
    ----------
    EI : complex, N m^2
    kGA : complex, N
    length : float, m

    Returns
    -------
    (4, 4) complex
    """
    L = length
    P = 12.0 * EI / (kGA * L**2)
    a = EI / ((1.0 + P) * L**3)
    return a * np.array([
        [12, 6 * L, -12, 6 * L],
        [6 * L, (4 + P) * L**2, -6 * L, (2 - P) * L**2],
        [-12, -6 * L, 12, -6 * L],
        [6 * L, (2 - P) * L**2, -6 * L, (4 + P) * L**2],
    ], dtype=complex)


def element_stiffness_quadrature(EI: float, kGA: float, length: float) -> np.ndarray:
    """Stiffness by Gauss quadrature of the strain energy (real moduli; verification of the closed form).

    Returns
    -------
    (4, 4) float
    """
    P = 12.0 * EI / (kGA * length**2)
    Nu, Nt, dNu, dNt = shape_functions(_XI, length, P)
    gamma = dNu - Nt
    K = EI * np.einsum("q,qi,qj->ij", _W, dNt, dNt) + kGA * np.einsum("q,qi,qj->ij", _W, gamma, gamma)
    return K * length


def element_mass(rhoA: float, rhoI: float, length: float, phi: float) -> np.ndarray:
    """Consistent mass with rotary inertia.

    Parameters
    ----------
    rhoA : float, kg/m
    rhoI : float, kg m
    length : float, m
    phi : float
        Shear parameter (real).

    Returns
    -------
    (4, 4) float, kg / kg m / kg m^2
    """
    Nu, Nt, _, _ = shape_functions(_XI, length, phi)
    M = rhoA * np.einsum("q,qi,qj->ij", _W, Nu, Nu) + rhoI * np.einsum("q,qi,qj->ij", _W, Nt, Nt)
    return M * length
