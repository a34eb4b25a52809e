"""Planning models of the Kinematic3D families.

Each model module imports kinder_garden3d lazily (inside the module), so kinder-gym imports
without the 3D extra.
"""
