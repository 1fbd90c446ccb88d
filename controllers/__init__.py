"""Pure numerics of the closed loop: plant, controllers, trajectories, indexes.

Never imports typer, h5py or matplotlib.
"""
