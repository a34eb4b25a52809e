"""Planning models of the Kinematic3D families (import kinder_garden3d lazily, inside each model module)."""
