"""
The web viewer: a WebGL2 executor of the same render graphs and GLSL ES 3.00 sources
as the moderngl runtime (:mod:`lbscene.runtimes.web.export` writes the static folder,
``assets/`` holds its HTML and JavaScript).
"""
