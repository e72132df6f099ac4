"""An independent ride generator: EUC and rider dynamics, controllers, excitation and Motive exports.

It shares no code with the model used for identification (the model and states packages), the residual
analysis or the project's ride simulator: the dynamics are derived here by Newton-Euler with the
constraint forces as unknowns (:mod:`.dynamics`), the EUC's balance loop and the rider's ankle loop
are controllers of their own (:mod:`.control`), the excitation is band-limited noise and random
speed profiles (:mod:`.excitation`), the rider is a rigid set of anthropometric segments
(:mod:`.body`), and the files are written by a writer of their own (:mod:`.writers`).

Typical use::

    from euc_ros.core.worldsim import simulate_ride, write_ride, Capture
    ride = simulate_ride(seed=3, rate_hz=120.0, duration=30.0)
    write_ride(ride, "out/", Capture(world_up="y", noise_pos_mm=0.2, noise_rot_deg=0.5), seed=3)

Only numpy and scipy are used (and :mod:`euc_ros.core.errors` for its exceptions).
"""
from euc_ros.core.worldsim.dynamics import PlantParams
from euc_ros.core.worldsim.simulate import Ride, RideSpec, draw_spec, simulate, simulate_ride
from euc_ros.core.worldsim.writers import Capture, write_ride

__all__ = ["Capture", "PlantParams", "Ride", "RideSpec", "draw_spec", "simulate", "simulate_ride", "write_ride"]
