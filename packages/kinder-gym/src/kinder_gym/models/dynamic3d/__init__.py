"""Planning models of the Dynamic3D families (import kinder_garden3d lazily, inside each model module)."""
