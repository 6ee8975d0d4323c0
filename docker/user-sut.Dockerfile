# syntax=docker/dockerfile:1
# A user's own SUT as a container, built ONLY from examples/ (the build context) and the topic
# contract (docs/topics.md): no evoscen package inside. It answers on /evoscen/commands/sut in a
# compose graph started with --external-sut (docker/compose-run.sh --user-sut).
#   docker build -f docker/user-sut.Dockerfile -t evoscen-user-sut examples/
ARG BASE=docker.io/library/debian:bookworm-slim
FROM ${BASE}
ENV DEBIAN_FRONTEND=noninteractive LANG=C.UTF-8 PYTHONUNBUFFERED=1 RMW_IMPLEMENTATION=rmw_fastrtps_cpp
RUN apt-get update -qq && apt-get install -y -qq --no-install-recommends python3.11 python3.11-venv ca-certificates \
 && rm -rf /var/lib/apt/lists/* /var/cache/apt/*
# rclpy + the standard messages + Fast DDS from PyPI wheels, numpy: all the example needs
RUN --mount=type=secret,id=pipconf,target=/etc/pip.conf \
    python3.11 -m venv /opt/sut && /opt/sut/bin/pip install --no-cache-dir --quiet \
      ros-jazzy-rclpy==7.1.6 ros-jazzy-common-interfaces==5.3.6 ros-jazzy-rmw-fastrtps-cpp==8.4.3 numpy==2.4.6
COPY external_sut_node.py /opt/sut/external_sut_node.py
RUN useradd --uid 10001 --create-home --shell /usr/sbin/nologin sut
USER sut
ENTRYPOINT ["/opt/sut/bin/python", "/opt/sut/external_sut_node.py"]
