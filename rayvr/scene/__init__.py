"""What is rendered: the loaded scene, the material config that picks each material's effect, and both
on the GPU.
"""
