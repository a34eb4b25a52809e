"""KinDERGarden 3D."""
