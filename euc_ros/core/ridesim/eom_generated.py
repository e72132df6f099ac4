"""Numeric truth equations, printed from the sympy derivation of :mod:`.eom_derivation`: do not edit.

Written by :mod:`euc_ros.core.ridesim.eom_codegen` (``python -m euc_ros.core.ridesim.eom_codegen``).
Each function returns a tuple of floats or of broadcasting numpy arrays; the arguments are the
derivation's symbols (SI units, rad), the physical parameters last in the order of
:class:`~euc_ros.core.ridesim.truth_model.PlanarParams` (m, m0, mw, Jw, J0, J, R, l0, h0).
"""
# ruff: noqa: E501
import numpy


def planar_mass(gamma, phi, h, m, m0, mw, Jw, J0, J, R, l0, h0):
    """Mass matrix M: the upper triangle of the symmetric 3x3 row by row (6 entries)."""
    c_0 = numpy.cos(gamma)
    c_1 = l0*m
    c_2 = c_0*c_1
    c_3 = numpy.cos(phi)
    c_4 = c_3*h
    c_5 = numpy.sin(gamma)
    c_6 = c_5**2
    c_7 = h0**2*m0
    c_8 = c_0**2
    c_9 = l0**2*m
    c_10 = numpy.sin(phi)
    c_11 = h**2*m
    return (Jw/R**2 + m + m0 + mw, c_0*h0*m0 - c_2, c_4*m, J0 + c_6*c_7 + c_6*c_9 + c_7*c_8 + c_8*c_9, -c_1*c_10*c_5*h - c_2*c_4, J + c_10**2*c_11 + c_11*c_3**2)


def planar_bias(gamma, phi, x_d, gamma_d, phi_d, h, h_d, h_dd, g_x, g_z, m, m0, mw, Jw, J0, J, R, l0, h0):
    """Bias vector b: velocity terms, rheonomic h(t) terms and minus the gravity forces."""
    c_0 = g_x*m
    c_1 = g_x*m0
    c_2 = numpy.sin(phi)
    c_3 = numpy.cos(phi)
    c_4 = gamma_d**2
    c_5 = numpy.sin(gamma)
    c_6 = c_4*c_5
    c_7 = phi_d**2
    c_8 = c_2*m
    c_9 = c_8*h
    c_10 = numpy.cos(gamma)
    c_11 = l0*m
    c_12 = c_10*l0
    c_13 = 2*h_d*phi_d
    c_14 = c_3*h
    c_15 = c_13*h*m
    return (-c_0 - c_1 + c_2*h_dd*m + 2*c_3*h_d*m*phi_d + c_4*c_5*l0*m - c_6*h0*m0 - c_7*c_9 - g_x*mw, -c_1*c_10*h0 - c_10*c_11*c_13*c_3 + c_10*c_2*c_7*h*l0*m + c_10*g_x*l0*m - c_11*c_14*c_5*c_7 - c_11*c_5*g_z - c_12*c_8*h_dd - c_13*c_5*c_8*l0 + c_3*c_5*h_dd*l0*m + c_5*g_z*h0*m0, -c_0*c_14 + c_11*c_14*c_6 - c_12*c_4*c_9 + c_15*c_2**2 + c_15*c_3**2 + c_9*g_z)


def planar_jac_g(gamma, phi, h, m, m0, mw, Jw, J0, J, R, l0, h0):
    """Rider CoG Jacobian dG/dq (2x3), row-major."""
    return (1.0, -l0*numpy.cos(gamma), h*numpy.cos(phi), 0.0, l0*numpy.sin(gamma), -h*numpy.sin(phi))


def planar_vel_g(gamma, phi, x_d, gamma_d, phi_d, h, h_d, m, m0, mw, Jw, J0, J, R, l0, h0):
    """In-plane velocity of the rider CoG G, including the h_dot term."""
    c_0 = numpy.sin(phi)
    c_1 = numpy.cos(phi)
    c_2 = h*phi_d
    c_3 = gamma_d*l0
    return (c_0*h_d + c_1*c_2 - c_3*numpy.cos(gamma) + x_d, -c_0*c_2 + c_1*h_d + c_3*numpy.sin(gamma))


def floor_mass(gamma, phi, h, a, m, m0, mw, Jw, J0, J, R, l0, h0):
    """Mass matrix M: the upper triangle of the symmetric 3x3 row by row (6 entries)."""
    c_0 = numpy.sin(a)
    c_1 = c_0**2
    c_2 = numpy.cos(a)
    c_3 = c_2**2
    c_4 = numpy.sin(gamma)
    c_5 = numpy.cos(gamma)
    c_6 = l0*m
    c_7 = numpy.sin(phi)
    c_8 = numpy.cos(phi)
    c_9 = c_4**2
    c_10 = h0**2*m0
    c_11 = c_5**2
    c_12 = l0**2*m
    c_13 = c_6*h
    c_14 = h**2*m
    return (Jw/R**2 + c_1*m + c_1*m0 + c_1*mw + c_3*m + c_3*m0 + c_3*mw, -c_0*c_4*h0*m0 + c_0*c_4*l0*m - c_2*c_5*c_6 + c_2*c_5*h0*m0, -c_0*c_7*h*m + c_2*c_8*h*m, J0 + c_10*c_11 + c_10*c_9 + c_11*c_12 + c_12*c_9, -c_13*c_4*c_7 - c_13*c_5*c_8, J + c_14*c_7**2 + c_14*c_8**2)


def floor_bias(gamma, phi, x_d, gamma_d, phi_d, h, h_d, h_dd, g_x, g_z, a, a1, m, m0, mw, Jw, J0, J, R, l0, h0):
    """Bias vector b: velocity terms, rheonomic h(t) terms and minus the gravity forces."""
    c_0 = numpy.cos(a)
    c_1 = c_0*g_x
    c_2 = numpy.sin(a)
    c_3 = c_2*g_z
    c_4 = numpy.cos(phi)
    c_5 = numpy.sin(phi)
    c_6 = 2*h_d*phi_d
    c_7 = numpy.cos(gamma)
    c_8 = c_2*c_7
    c_9 = gamma_d**2
    c_10 = h0*m0
    c_11 = c_10*c_9
    c_12 = numpy.sin(gamma)
    c_13 = c_0*c_12
    c_14 = c_2*c_4
    c_15 = phi_d**2
    c_16 = h*m
    c_17 = c_15*c_16
    c_18 = c_0*c_5
    c_19 = l0*m
    c_20 = c_5*c_7
    c_21 = c_19*c_6
    c_22 = x_d**2
    c_23 = a1*c_22
    c_24 = c_10*c_23
    c_25 = c_16*c_23
    return (c_0*c_12*c_9*l0*m + 2*c_0*c_4*h_d*m*phi_d + c_0*c_5*h_dd*m - c_1*m - c_1*m0 - c_1*mw - c_11*c_13 - c_11*c_8 - c_14*c_17 - c_17*c_18 + c_2*c_4*h_dd*m - c_2*c_5*c_6*m + c_2*c_7*c_9*l0*m - c_3*m - c_3*m0 - c_3*mw, a1*c_0*c_12*c_22*l0*m + a1*c_2*c_22*c_7*l0*m - c_10*c_7*g_x - c_12*c_15*c_19*c_4*h - c_12*c_19*g_z - c_12*c_21*c_5 + c_12*c_4*h_dd*l0*m + c_12*g_z*h0*m0 - c_13*c_24 + c_15*c_5*c_7*h*l0*m - c_20*h_dd*l0*m - c_21*c_4*c_7 - c_24*c_8 + c_7*g_x*l0*m, c_12*c_4*c_9*h*l0*m - c_14*c_25 - c_16*c_4*g_x - c_18*c_25 - c_19*c_20*c_9*h + 2*c_4**2*h*h_d*m*phi_d + 2*c_5**2*h*h_d*m*phi_d + c_5*g_z*h*m)


def pedal_mass(gamma, phi, u, h, m, m0, mw, Jw, J0, J, R, l0, h0):
    """Mass matrix M: all 16 entries of the 4x4, row-major."""
    c_0 = numpy.cos(gamma)
    c_1 = c_0*m
    c_2 = c_1*l0
    c_3 = c_1*u
    c_4 = c_0*h0*m0 - c_2 - c_3
    c_5 = numpy.cos(phi)
    c_6 = c_5*h
    c_7 = c_6*m
    c_8 = numpy.sin(gamma)
    c_9 = c_8*m
    c_10 = -c_9
    c_11 = c_8**2
    c_12 = h0**2*m0
    c_13 = c_0**2
    c_14 = l0**2
    c_15 = c_11*m
    c_16 = c_13*m
    c_17 = u**2
    c_18 = 2*l0*u
    c_19 = numpy.sin(phi)
    c_20 = c_19*c_9*h
    c_21 = -c_2*c_6 - c_20*l0 - c_20*u - c_3*c_6
    c_22 = h**2*m
    c_23 = c_0*c_19*h*m - c_6*c_9
    return (Jw/R**2 + m + m0 + mw, c_4, c_7, c_10, c_4, J0 + c_11*c_12 + c_12*c_13 + c_14*c_15 + c_14*c_16 + c_15*c_17 + c_15*c_18 + c_16*c_17 + c_16*c_18, c_21, 0.0, c_7, c_21, J + c_19**2*c_22 + c_22*c_5**2, c_23, c_10, 0.0, c_23, c_15 + c_16)


def pedal_bias(gamma, phi, u, x_d, gamma_d, phi_d, u_d, h, h_d, h_dd, g_x, g_z, m, m0, mw, Jw, J0, J, R, l0, h0):
    """Bias vector b: velocity terms, rheonomic h(t) terms and minus the gravity forces."""
    c_0 = g_x*m
    c_1 = g_x*m0
    c_2 = numpy.sin(phi)
    c_3 = numpy.cos(gamma)
    c_4 = c_3*m
    c_5 = 2*gamma_d*u_d
    c_6 = c_4*c_5
    c_7 = numpy.cos(phi)
    c_8 = numpy.sin(gamma)
    c_9 = gamma_d**2
    c_10 = phi_d**2
    c_11 = c_2*m
    c_12 = c_11*h
    c_13 = c_8*g_z*m
    c_14 = c_11*h_dd
    c_15 = c_14*c_3
    c_16 = c_8**2
    c_17 = c_3**2
    c_18 = 2*h_d*phi_d
    c_19 = c_11*c_18*c_8
    c_20 = l0*m
    c_21 = c_18*c_3*c_7
    c_22 = m*u
    c_23 = c_7*h
    c_24 = c_10*c_23*c_8
    c_25 = c_12*c_3*c_9
    c_26 = c_20*c_9
    c_27 = c_22*c_9
    return (-c_0 - c_1 - c_10*c_12 + c_2*h_dd*m - c_6 + 2*c_7*h_d*m*phi_d - c_8*c_9*h0*m0 + c_8*c_9*l0*m + c_8*c_9*m*u - g_x*mw, -c_1*c_3*h0 + c_10*c_2*c_3*h*l0*m + c_10*c_2*c_3*h*m*u - c_13*l0 - c_13*u - c_15*l0 - c_15*u + 2*c_16*gamma_d*l0*m*u_d + 2*c_16*gamma_d*m*u*u_d + 2*c_17*gamma_d*l0*m*u_d + 2*c_17*gamma_d*m*u*u_d - c_19*l0 - c_19*u - c_20*c_21 - c_20*c_24 - c_21*c_22 - c_22*c_24 + c_3*g_x*l0*m + c_3*g_x*m*u + c_7*c_8*h_dd*l0*m + c_7*c_8*h_dd*m*u + c_8*g_z*h0*m0, -c_0*c_23 - c_12*c_5*c_8 + 2*c_2**2*h*h_d*m*phi_d + c_2*g_z*h*m - c_23*c_6 - c_25*l0 - c_25*u + 2*c_7**2*h*h_d*m*phi_d + c_7*c_8*c_9*h*l0*m + c_7*c_8*c_9*h*m*u, c_10*c_2*c_8*h*m + c_10*c_3*c_7*h*m - c_14*c_8 - c_16*c_26 - c_16*c_27 - c_17*c_26 - c_17*c_27 - c_18*c_7*c_8*m + 2*c_2*c_3*h_d*m*phi_d + c_3*g_z*m - c_4*c_7*h_dd + c_8*g_x*m)


__all__ = ["planar_mass", "planar_bias", "planar_jac_g", "planar_vel_g", "floor_mass", "floor_bias", "pedal_mass", "pedal_bias"]
