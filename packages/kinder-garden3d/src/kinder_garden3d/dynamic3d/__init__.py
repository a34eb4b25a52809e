"""Dynamic3D: MuJoCo mobile-manipulation tasks defined by task files (environments.md §5).

One environment class (:class:`kinder_garden3d.dynamic3d.env.Dynamic3DEnv`) runs every task;
tasks differ only in their files under ``tasks/<Family>/`` (schema: ``taskfile.py`` and the
package README). Importing this package does not import MuJoCo.
"""
