"""evoscen background-vehicle drivers: level-0, the learned social drivers (TD3, level-k) and their
training, the highD make-up's trucks, the BV node. May import the SUT models (the BVs follow like
SUTs), the simulation and the contract."""

from evoscen_sim.moved_paths import install as _install_moved_paths

_install_moved_paths()  # the 0.6 paths of moved modules keep working until 0.8.0, with a DeprecationWarning
