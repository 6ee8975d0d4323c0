# syntax=docker/dockerfile:1
# The fiss SUT plug-in (examples/fiss_sut: FISS+ from fiss-planner 1.0.0, PyPI, pinned) on top of
# evoscen's runtime image: one layer more. Its container is the graph's SUT node (compose profile
# fiss-sut); the other nodes run this image too, because every node checks the scenario, whose
# sut.model is fiss (docs/docker.md, "A third-party planner as its own container").
#   docker build -f docker/fiss-sut.Dockerfile -t evoscen-fiss .   (after the runtime image)
ARG RUNTIME=localhost/evoscen:latest
FROM ${RUNTIME}
USER root
COPY requirements-runtime.txt /tmp/fiss/requirements-runtime.txt
COPY examples/fiss_sut /tmp/fiss/fiss_sut
# -c requirements-runtime.txt: none of evoscen's pinned versions (numpy, ...) changes on the way
RUN --mount=type=secret,id=pipconf,target=/etc/pip.conf \
    /opt/evoscen/.venv/bin/pip install --no-cache-dir --quiet -c /tmp/fiss/requirements-runtime.txt /tmp/fiss/fiss_sut \
 && rm -rf /tmp/fiss
USER evoscen
