"""1-D transient heat conduction in a slab with a surface energy balance (scene surfaces).

Ground, walls and panels are layered slabs: finite-volume heat equation on N layers with
N + 1 nodes (node 0 is the surface, node N the bottom), the top node exchanging heat with the
environment (absorbed sun, sky long wave, convection), the bottom adiabatic or held at a deep
temperature. Time stepping is implicit (theta method, backward Euler by default) with the
nonlinear emission term Newton-linearized and iterated to convergence, so 10-minute steps are
stable. This is the role of DIRSIG's THERM model in the seed.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_banded

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.physics import evaporation as ev

#: combined inside surface coefficient of a wall, 1 / R_si with R_si = 0.13 m^2 K W^-1
#: (ISO 6946:2017, Table 7, horizontal heat flow) [W m^-2 K^-1]
INTERIOR_SURFACE_COEFFICIENT = 1.0 / 0.13


def uniform_layers(total_thickness_m, n_layers):
    """Layer thicknesses of a uniformly divided slab.

    Parameters
    ----------
    total_thickness_m : float
        Slab thickness [m].
    n_layers : int
        Number of layers [-].

    Returns
    -------
    numpy.ndarray
        Layer thicknesses [m], shape (n_layers,).
    """
    return np.full(int(n_layers), float(total_thickness_m) / int(n_layers))


def surface_flux(surface_temperature_k, absorbed_solar, sky_longwave, air_temperature_k, h_conv, emissivity):
    """Net heat flux into the top surface [W m^-2].

    Parameters
    ----------
    surface_temperature_k : numeric
        Surface temperature [K].
    absorbed_solar : numeric
        Absorbed short wave alpha G [W m^-2].
    sky_longwave : numeric
        Downwelling long-wave irradiance L_sky [W m^-2].
    air_temperature_k : numeric
        Air temperature [K].
    h_conv : numeric
        Convective coefficient [W m^-2 K^-1].
    emissivity : numeric
        Long-wave emissivity (= absorptance) [0-1].

    Returns
    -------
    numeric
        q_s = alpha G + eps (L_sky - sigma T^4) + h (T_air - T) [W m^-2].

    References
    ----------
    .. [1] Incropera et al. (2007), Fundamentals of Heat and Mass Transfer, 6th ed., section 1.3.1
       (surface energy balance).
    """
    t = np.asarray(surface_temperature_k, dtype=float)
    return (
        np.asarray(absorbed_solar, dtype=float)
        + emissivity * (sky_longwave - STEFAN_BOLTZMANN * t**4)
        + h_conv * (air_temperature_k - t)
    )


def _operators(layer_thickness_m, conductivity, volumetric_heat_capacity):
    dz = np.asarray(layer_thickness_m, dtype=float)
    n = dz.size
    k = np.broadcast_to(np.asarray(conductivity, dtype=float), (n,))
    rc = np.broadcast_to(np.asarray(volumetric_heat_capacity, dtype=float), (n,))
    g = k / dz  # conductance between nodes i and i + 1 [W m^-2 K^-1]
    cap = np.zeros(n + 1)  # node heat capacity per area [J m^-2 K^-1]
    cap[:-1] += 0.5 * rc * dz
    cap[1:] += 0.5 * rc * dz
    return g, cap


def _conduction(t, g):
    """Net conductive flux into each node [W m^-2]."""
    q = np.zeros_like(t)
    f = g * (t[1:] - t[:-1])  # from node i+1 to node i
    q[:-1] += f
    q[1:] -= f
    return q


def step(
    temperatures_k,
    time_step_s,
    layer_thickness_m,
    conductivity,
    volumetric_heat_capacity,
    absorbed_solar,
    sky_longwave,
    air_temperature_k,
    h_conv,
    emissivity=0.95,
    bottom="adiabatic",
    deep_temperature_k=None,
    theta=1.0,
    tol=1e-9,
    max_iter=50,
):
    """Advance a slab's node temperatures by one implicit step.

    Parameters
    ----------
    temperatures_k : array_like
        Node temperatures at the start of the step, surface first [K], shape (N + 1,).
    time_step_s : float
        Time step [s]; ``np.inf`` gives the steady state (with ``theta=1``).
    layer_thickness_m : array_like
        Layer thicknesses [m], shape (N,); see :py:func:`uniform_layers`.
    conductivity : numeric
        Layer thermal conductivity [W m^-1 K^-1], scalar or shape (N,).
    volumetric_heat_capacity : numeric
        Layer rho c [J m^-3 K^-1], scalar or shape (N,).
    absorbed_solar : float
        Absorbed short wave alpha G at the end of the step [W m^-2].
    sky_longwave : float
        Downwelling long wave L_sky [W m^-2].
    air_temperature_k : float
        Air temperature [K].
    h_conv : float
        Convective coefficient [W m^-2 K^-1].
    emissivity : float, default 0.95
        Surface long-wave emissivity [0-1].
    bottom : str, default 'adiabatic'
        'adiabatic' (no flux) or 'fixed' (bottom node held at ``deep_temperature_k``).
    deep_temperature_k : float, optional
        Bottom temperature for ``bottom='fixed'`` [K].
    theta : float, default 1
        Implicitness: 1 backward Euler (L-stable, no oscillation), 0.5 Crank-Nicolson
        (second order, may ring on steps much longer than dz^2 / alpha).
    tol : float, default 1e-9
        Newton tolerance on the node temperature change [K].
    max_iter : int, default 50
        Newton iteration cap.

    Returns
    -------
    tuple
        (node temperatures at the end of the step [K], surface energy residual [W m^-2]:
        q_s + conduction - storage at the surface node, 0 at convergence).

    Raises
    ------
    ValueError
        If ``bottom`` is not 'adiabatic' or 'fixed'.

    Notes
    -----
    Finite-volume (vertex-centred) heat equation, node capacities C_i = (rho c dz)_{i-1}/2 +
    (rho c dz)_i / 2, conductances G_i = k_i / dz_i:
    C (T^{n+1} - T^n) / dt = theta R(T^{n+1}) + (1 - theta) R(T^n), with
    R_i = G_{i-1} (T_{i-1} - T_i) + G_i (T_{i+1} - T_i) + delta_{i0} q_s(T_0). The surface term
    q_s = alpha G + eps (L_sky - sigma T_0^4) + h (T_air - T_0) is Newton-linearized,
    dq_s/dT_0 = -4 eps sigma T_0^3 - h, and the tridiagonal system re-solved until the update
    is below ``tol``. Piecewise-linear steady profiles are reproduced exactly.

    References
    ----------
    .. [1] Patankar, S. V. (1980). Numerical Heat Transfer and Fluid Flow, Hemisphere, ch. 4.
    .. [2] Incropera et al. (2007), section 5.10 (finite-difference transient conduction).
    .. [3] Schott, J. R. et al. DIRSIG THERM: the surface temperature model of DIRSIG,
       Rochester Institute of Technology.
    """
    if bottom not in ("adiabatic", "fixed"):
        raise ValueError(f"invalid model selection {bottom}")
    t_old = np.asarray(temperatures_k, dtype=float)
    g, cap = _operators(layer_thickness_m, conductivity, volumetric_heat_capacity)
    n1 = t_old.size
    if n1 != g.size + 1:
        raise ValueError("temperatures_k needs one more entry than layer_thickness_m")
    c_dt = cap / time_step_s
    forcing = (absorbed_solar, sky_longwave, air_temperature_k, h_conv, emissivity)
    explicit = np.zeros(n1)
    if theta < 1.0:
        explicit = _conduction(t_old, g)
        explicit[0] += surface_flux(t_old[0], *forcing)
        explicit *= 1.0 - theta
    # tridiagonal Jacobian of  c_dt (T - T_old) - theta R(T) - explicit
    ab = np.zeros((3, n1))
    diag = c_dt.copy()
    diag[:-1] += theta * g
    diag[1:] += theta * g
    ab[0, 1:] = -theta * g  # upper
    ab[2, :-1] = -theta * g  # lower
    t = t_old.copy()
    if bottom == "fixed":
        t[-1] = deep_temperature_k
    for _ in range(max_iter):
        res = c_dt * (t - t_old) - theta * _conduction(t, g) - explicit
        res[0] -= theta * surface_flux(t[0], *forcing)
        jac = ab.copy()
        jac[1] = diag
        jac[1, 0] += theta * (4.0 * emissivity * STEFAN_BOLTZMANN * t[0] ** 3 + h_conv)
        if bottom == "fixed":
            res[-1] = 0.0
            jac[1, -1] = 1.0
            jac[2, -2] = 0.0  # row N is the identity
        dt_nodes = solve_banded((1, 1), jac, -res)
        t = t + dt_nodes
        if np.max(np.abs(dt_nodes)) < tol:
            break
    residual = (
        theta * (surface_flux(t[0], *forcing) + g[0] * (t[1] - t[0]))
        + explicit[0]
        - c_dt[0] * (t[0] - t_old[0])
    )
    return t, residual


def diurnal_spin_up(
    initial_temperature_k,
    time_step_s,
    layer_thickness_m,
    conductivity,
    volumetric_heat_capacity,
    absorbed_solar,
    sky_longwave,
    air_temperature_k,
    h_conv,
    emissivity=0.95,
    n_cycles=1,
    bottom="adiabatic",
    deep_temperature_k=None,
    theta=1.0,
):
    """Run a slab through repeated diurnal forcing (24 h spin-up) and return the last cycle.

    Parameters
    ----------
    initial_temperature_k : numeric
        Initial node temperatures [K], scalar (uniform) or shape (N + 1,).
    time_step_s : float
        Step of the forcing arrays [s], e.g. 600 for 144 samples per day.
    layer_thickness_m, conductivity, volumetric_heat_capacity, emissivity, bottom, \
deep_temperature_k, theta
        As in :py:func:`step`.
    absorbed_solar, sky_longwave, air_temperature_k, h_conv : array_like
        Forcing at the end of each step over one cycle [W m^-2, W m^-2, K, W m^-2 K^-1],
        each of length M (or scalars).
    n_cycles : int, default 1
        Number of cycles; the profile at the end of one is the start of the next.

    Returns
    -------
    tuple
        (surface temperature over the last cycle [K], shape (M,); node temperatures over the
        last cycle [K], shape (M, N + 1); max |surface residual| over all steps [W m^-2]).
    """
    dz = np.asarray(layer_thickness_m, dtype=float)
    t = np.broadcast_to(np.asarray(initial_temperature_k, dtype=float), (dz.size + 1,)).copy()
    forcing = np.broadcast_arrays(
        *[
            np.atleast_1d(np.asarray(f, dtype=float))
            for f in (absorbed_solar, sky_longwave, air_temperature_k, h_conv)
        ]
    )
    m = forcing[0].size
    history = np.empty((m, dz.size + 1))
    max_res = 0.0
    for _ in range(int(n_cycles)):
        for i in range(m):
            t, res = step(
                t,
                time_step_s,
                dz,
                conductivity,
                volumetric_heat_capacity,
                forcing[0][i],
                forcing[1][i],
                forcing[2][i],
                forcing[3][i],
                emissivity,
                bottom,
                deep_temperature_k,
                theta,
            )
            history[i] = t
            max_res = max(max_res, abs(float(res)))
    return history[:, 0].copy(), history, max_res


def held_temperature(set_temperature_k, n_steps):
    """Surface temperature of a controlled (blackbody) panel: the set point at every step.

    Parameters
    ----------
    set_temperature_k : numeric
        Set temperature [K], scalar or shape (n_steps,).
    n_steps : int
        Number of time steps [-].

    Returns
    -------
    numpy.ndarray
        Surface temperature [K], shape (n_steps,); no heat balance is solved.
    """
    return np.broadcast_to(np.asarray(set_temperature_k, dtype=float), (int(n_steps),)).copy()


def step_many(
    temperatures_k,
    time_step_s,
    layer_thickness_m,
    conductivity,
    volumetric_heat_capacity,
    absorbed_solar,
    sky_longwave,
    air_temperature_k,
    h_conv,
    emissivity=0.95,
    bottom="adiabatic",
    deep_temperature_k=None,
    tol=1e-9,
    max_iter=50,
    back_h_w_m2k=INTERIOR_SURFACE_COEFFICIENT,
    evaporation_beta=None,
    vapour_pressure_pa=None,
    pressure_pa=101325.0,
    melt_temperature_k=None,
    return_melt_flux=False,
):
    """Backward-Euler step of many slabs of one construction at once (vectorized :func:`step`).

    Parameters
    ----------
    temperatures_k : array (F, N + 1)
        Node temperatures of F slabs at the start of the step, surface first [K].
    time_step_s : float
        Time step [s]; ``np.inf`` gives the steady state.
    layer_thickness_m, conductivity, volumetric_heat_capacity
        As in :func:`step` (one construction shared by the F slabs).
    bottom : str
        'adiabatic', 'fixed' (node N held at ``deep_temperature_k``) or 'interior': the back
        exchanges heat with room air at ``deep_temperature_k`` through the combined inside
        surface coefficient ``back_h_w_m2k`` (convection + radiation to the room,
        q = h_i (T_room - T_N); ISO 6946:2017 R_si = 0.13 m^2 K W^-1 for horizontal heat flow,
        h_i = 7.7 W m^-2 K^-1, :data:`INTERIOR_SURFACE_COEFFICIENT`).
    absorbed_solar, sky_longwave, air_temperature_k, h_conv, emissivity, deep_temperature_k :
        numeric or (F,)
        Forcing at the end of the step per slab, as in :func:`step`.
    tol, max_iter
        Newton tolerance on the node update [K] and iteration cap.
    evaporation_beta : numeric or (F,), optional
        Share of a free water surface's latent flux the surface passes
        (:func:`humv_usd.physics.evaporation.evaporation_efficiency`: stomatal resistance,
        wet fraction) [0-1]; None (default): a dry surface, no latent flux.
    vapour_pressure_pa : numeric or (F,), optional
        Vapour pressure of the air [Pa] (needed with ``evaporation_beta``).
    pressure_pa : numeric or (F,), default 101325
        Air pressure [Pa] (psychrometric constant).
    melt_temperature_k : float, optional
        The surface cannot rise above this (melting snow or ice: the surplus of the surface
        balance melts it, latent heat of fusion, the store of snow not tracked); None: no limit.
    return_melt_flux : bool, default False
        Also return the surplus the capped surface passes to melting [W m^-2] (0 where not
        melting; :func:`humv_usd.physics.snow.simulate_cover` tracks the snow with it).

    Returns
    -------
    tuple
        (node temperatures (F, N + 1) [K], surface energy residual (F,) [W m^-2]; 0 where
        the surface melts) and with ``return_melt_flux`` the melt flux (F,) [W m^-2].

    Notes
    -----
    Same discretisation as :func:`step` with theta = 1 (backward Euler, L-stable). Only the
    surface node is nonlinear, so the linear conduction rows are eliminated once per step from
    the bottom up (the Thomas algorithm run from node N, Patankar 1980, section 4.2-5:
    T_i = alpha_i T_{i-1} + beta_i, alpha shared by the F slabs of one construction), leaving
    one scalar equation per slab, (C_0/dt + G_0 (1 - alpha_1)) T_0 - b = q_s(T_0) - LE(T_0),
    solved by Newton (q_s - LE concave in T_0: e_s is convex); then back substitution. The
    result is the full system's. LE = beta h / gamma (e_s(T_0) - e_a): the latent flux in its
    surface-temperature form (:func:`humv_usd.physics.evaporation.latent_flux`).
    """
    if bottom not in ("adiabatic", "fixed", "interior"):
        raise ValueError(f"invalid model selection {bottom}")
    if bottom == "interior" and not (np.isfinite(back_h_w_m2k) and back_h_w_m2k >= 0.0):
        raise ValueError(f"back_h_w_m2k must be finite and >= 0, got {back_h_w_m2k!r}")
    t_old = np.atleast_2d(np.asarray(temperatures_k, dtype=float))
    nf, n1 = t_old.shape
    g, cap = _operators(layer_thickness_m, conductivity, volumetric_heat_capacity)
    if n1 != g.size + 1:
        raise ValueError("temperatures_k needs one more entry than layer_thickness_m")

    def col(v):
        return np.broadcast_to(np.asarray(v, dtype=float), (nf,))

    a_s, l_sky, t_air, h, eps = (
        col(v) for v in (absorbed_solar, sky_longwave, air_temperature_k, h_conv, emissivity)
    )
    c_dt = cap / time_step_s  # (n1,), shared by the F slabs
    # the conduction rows are linear and shared: eliminate them from the bottom up,
    # T_i = alpha_i T_{i-1} + beta_i (alpha shared, beta per slab), down to one scalar
    # equation for the surface node
    diag = c_dt.copy()
    diag[:-1] += g
    diag[1:] += g
    rhs = c_dt[None, :] * t_old
    n = n1 - 1
    alpha = np.zeros(n1)
    beta = np.empty((nf, n1))
    if bottom == "fixed":
        alpha[n], beta[:, n] = 0.0, col(deep_temperature_k)
    else:
        d_n = diag[n] + (back_h_w_m2k if bottom == "interior" else 0.0)
        r_n = rhs[:, n] + (back_h_w_m2k * col(deep_temperature_k) if bottom == "interior" else 0.0)
        alpha[n], beta[:, n] = g[n - 1] / d_n, r_n / d_n
    for i in range(n - 1, 0, -1):
        piv = diag[i] - g[i] * alpha[i + 1]
        alpha[i] = g[i - 1] / piv
        beta[:, i] = (rhs[:, i] + g[i] * beta[:, i + 1]) / piv
    # surface node: k T0 - b = q_s(T0), Newton (q_s concave in T0: monotone convergence)
    k0 = c_dt[0] + g[0] * (1.0 - alpha[1])
    b0 = rhs[:, 0] + g[0] * beta[:, 1]
    t0 = t_old[:, 0].copy()
    evaporating = evaporation_beta is not None

    def latent(temp):
        if not evaporating:
            return 0.0, 0.0
        return ev.latent_flux(
            temp, col(vapour_pressure_pa), h, col(evaporation_beta), col(pressure_pa), t_air
        )

    for _ in range(max_iter):
        le, dle = latent(t0)
        f = k0 * t0 - b0 - surface_flux(t0, a_s, l_sky, t_air, h, eps) + le
        d = f / (k0 + 4.0 * eps * STEFAN_BOLTZMANN * t0**3 + h + dle)
        t0 -= d
        if np.max(np.abs(d)) < tol:
            break
    melting = np.zeros(nf, dtype=bool)
    if melt_temperature_k is not None:
        melting = t0 > melt_temperature_k
        t0 = np.minimum(t0, melt_temperature_k)
    t = np.empty((nf, n1))
    t[:, 0] = t0
    for i in range(1, n1):
        t[:, i] = alpha[i] * t[:, i - 1] + beta[:, i]
    residual = (
        surface_flux(t[:, 0], a_s, l_sky, t_air, h, eps)
        - latent(t[:, 0])[0]
        + g[0] * (t[:, 1] - t[:, 0])
        - c_dt[0] * (t[:, 0] - t_old[:, 0])
    )
    if return_melt_flux:
        return t, np.where(melting, 0.0, residual), np.where(melting, residual, 0.0)
    return t, np.where(melting, 0.0, residual)


def simulate_many(
    forcing_times_s,
    absorbed_solar,
    sky_longwave,
    air_temperature_k,
    h_conv,
    layer_thickness_m,
    conductivity,
    volumetric_heat_capacity,
    emissivity=0.95,
    bottom="adiabatic",
    deep_temperature_k=None,
    initial_temperature_k=None,
    back_h_w_m2k=INTERIOR_SURFACE_COEFFICIENT,
    surface_resistance_s_m=None,
    vapour_pressure_pa=None,
    pressure_pa=101325.0,
    rain_kg_m2_s=0.0,
    water_capacity_kg_m2=0.0,
    return_wet_fraction=False,
    melt_temperature_k=None,
):
    """Surface temperatures of F slabs of one construction along a forcing time series.

    Parameters
    ----------
    forcing_times_s : array (M,)
        Increasing sample times [s]; the state starts at the first (in equilibrium with the
        forcing averaged over all samples, or at ``initial_temperature_k``), and each later
        sample ends one backward-Euler step.
    absorbed_solar, sky_longwave, air_temperature_k, h_conv : array (M, F) or broadcastable
        Forcing per sample and slab, as in :func:`step`.
    layer_thickness_m, conductivity, volumetric_heat_capacity, emissivity, bottom, \
deep_temperature_k, back_h_w_m2k
        As in :func:`step_many`.
    initial_temperature_k : numeric or (F, N + 1), optional
        Initial node temperatures instead of the mean-forcing steady state.
    surface_resistance_s_m : array (M, F) or broadcastable, optional
        Surface (stomatal) resistance of the dry surface [s m^-1] (``np.inf``: no evaporation
        from the dry part); None (default): a dry surface without latent flux (the model before
        issue 30), and no water film either.
    vapour_pressure_pa, pressure_pa : array (M, F) or broadcastable
        Vapour pressure of the air and air pressure [Pa] (with ``surface_resistance_s_m``).
    rain_kg_m2_s : array (M, F) or broadcastable, default 0
        Rain rate over the step ending at each sample [kg m^-2 s^-1] (1 mm h^-1 = 1/3600).
    water_capacity_kg_m2 : numeric or (F,), default 0
        Water the surface holds as a film or in puddles before it runs off [kg m^-2 = mm].
    return_wet_fraction : bool, default False
        Also return the wet fraction (M, F) [0-1].
    melt_temperature_k : float, optional
        As in :func:`step_many` (snow: 273.15).

    Returns
    -------
    tuple
        (surface temperature (M, F) [K], max |surface residual| [W m^-2]) and with
        ``return_wet_fraction`` the wet fraction (M, F).

    Notes
    -----
    Water on the surface (rain, dew) is an interception reservoir W [kg m^-2] (Noilhan &
    Planton 1989, eq. 30; Deardorff 1978): over each step dW/dt = P - E_wet, 0 <= W <=
    W_max, with E_wet = delta h / gamma (e_s(T_0) - e_a) / lambda the free-water evaporation of
    the wet share delta = (W / W_max)^(2/3) (negative: dew); the step's latent flux uses
    beta = delta + (1 - delta) r_a / (r_a + r_s) with delta at the start of the step (the
    reservoir is updated explicitly after the implicit temperature step). A surface dries
    after rain at the rate its energy balance allows, and is near the wet-bulb temperature
    while wet.
    """
    times = np.asarray(forcing_times_s, dtype=float)
    m = times.size

    def as_2d(v):
        v = np.asarray(v, dtype=float)
        return v.reshape(-1, 1) if v.ndim == 1 else v

    evaporating = surface_resistance_s_m is not None
    more = (surface_resistance_s_m, vapour_pressure_pa, pressure_pa, rain_kg_m2_s) if evaporating else ()
    forcing = [as_2d(v) for v in (absorbed_solar, sky_longwave, air_temperature_k, h_conv, *more)]
    shape = np.broadcast_shapes(*[f.shape for f in forcing], (m, 1))
    forcing = [np.broadcast_to(f, shape) for f in forcing]
    nf = shape[1]
    capacity = np.broadcast_to(np.asarray(water_capacity_kg_m2, dtype=float), (nf,))
    water = np.zeros(nf)
    wet_out = np.zeros((m, nf))

    def latent_kw(i, wet):
        """step_many's latent arguments at sample i (a slice: the mean) with wet share ``wet``."""
        if not evaporating:
            return {}
        rs, ea, p = (forcing[k][i] for k in (4, 5, 6))
        if isinstance(i, slice):
            rs, ea, p = (np.mean(v, axis=0) for v in (rs, ea, p))
            air, hc = forcing[2][i].mean(axis=0), forcing[3][i].mean(axis=0)
        else:
            air, hc = forcing[2][i], forcing[3][i]
        beta = ev.evaporation_efficiency(hc, rs, p, air, wet)
        return {"evaporation_beta": beta, "vapour_pressure_pa": ea, "pressure_pa": p}

    n1 = np.asarray(layer_thickness_m).size + 1
    kw = dict(
        layer_thickness_m=layer_thickness_m,
        conductivity=conductivity,
        volumetric_heat_capacity=volumetric_heat_capacity,
        emissivity=emissivity,
        bottom=bottom,
        deep_temperature_k=deep_temperature_k,
        back_h_w_m2k=back_h_w_m2k,
        melt_temperature_k=melt_temperature_k,
    )
    if initial_temperature_k is None:
        # steady state of the time-mean forcing; the emission term is nonlinear, so the mean of
        # sigma T^4 is not matched exactly, which the spin-up removes
        mean = [f.mean(axis=0) for f in forcing]
        start = np.broadcast_to(mean[2][:, None], (nf, n1))
        t, _ = step_many(
            start,
            np.inf,
            absorbed_solar=mean[0],
            sky_longwave=mean[1],
            air_temperature_k=mean[2],
            h_conv=mean[3],
            **kw,
            **latent_kw(slice(None), 0.0),
        )
    else:
        t = np.broadcast_to(np.asarray(initial_temperature_k, dtype=float), (nf, n1)).copy()
    out = np.empty((m, nf))
    out[0] = t[:, 0]
    max_res = 0.0
    for i in range(1, m):
        dt = times[i] - times[i - 1]
        wet = ev.wet_fraction(water, capacity)
        t, res = step_many(
            t,
            dt,
            absorbed_solar=forcing[0][i],
            sky_longwave=forcing[1][i],
            air_temperature_k=forcing[2][i],
            h_conv=forcing[3][i],
            **kw,
            **latent_kw(i, wet),
        )
        out[i] = t[:, 0]
        max_res = max(max_res, float(np.max(np.abs(res))))
        if evaporating and np.any(capacity > 0.0):
            le_wet, _ = ev.latent_flux(
                t[:, 0], forcing[5][i], forcing[3][i], wet, forcing[6][i], forcing[2][i]
            )
            evap = le_wet / ev.latent_heat_of_vaporization(t[:, 0])
            water = np.clip(water + (forcing[7][i] - evap) * dt, 0.0, capacity)
            wet_out[i] = ev.wet_fraction(water, capacity)
    if return_wet_fraction:
        return out, max_res, wet_out
    return out, max_res
