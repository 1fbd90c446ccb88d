"""Pure numerics of axis identification (inverse-dynamics least squares).

Installed as ``commission.identify``.  Never imports typer, h5py or matplotlib.
"""
