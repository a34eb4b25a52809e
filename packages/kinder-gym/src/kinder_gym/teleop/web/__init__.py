"""The 3D teleop web app: message protocol, hub (the device), FastAPI server and page."""
