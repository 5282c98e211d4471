"""Emulated PI GCS 2.0 controllers: the TCP/pty server (``emulator``), the controller's
command set (``controller``), the simulated axis motion, the E-727-class piezo
controller, the data recorder, a family's campaign emulator (``campaign_emulator``: its
``gcs`` rig options, a started emulator for tests, the ``calflow emulate gcs`` main) and a
campaign's stages served until Ctrl-C (``campaign_server``).
"""
