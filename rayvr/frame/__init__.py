"""One frame from a plan: the graph of passes and its resources (G-buffer), the passes, the effects
that add them, the cameras (the stereo rig and the camera models), the stereo modes, sample
accumulation and the readback of the images. Importing the package imports nothing."""
