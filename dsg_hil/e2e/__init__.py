"""End-to-end tests on a real SocketCAN vcan0, shipped with the package so that ``dsg-hil vcan`` runs them from
any install (``pytest -m vcan --pyargs dsg_hil.e2e``): plant and TCU as separate processes through the console
scripts of this environment, recorded by candump, replayed by canplayer, decoded by cantools. Needs pytest
(extra ``vcan``)."""
