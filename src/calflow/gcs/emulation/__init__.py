"""Emulated PI GCS 2.0 controllers: the TCP/pty server (``emulator``), the controller's
command set (``controller``), the simulated axis motion, the E-727-class piezo
controller, the data recorder, and a campaign's stages served until Ctrl-C
(``campaign_server``).
"""
