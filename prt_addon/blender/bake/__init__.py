"""The transfer bake in Blender: settings, scene gathering, the job, its modal runner, reports."""
