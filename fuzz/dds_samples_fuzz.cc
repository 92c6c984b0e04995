// libFuzzer target: what a robot makes of the DDS samples it takes. The CDR bytes of a sample are
// deserialized as Cyclone DDS does on receipt (dds_stream_normalize_data checks every length,
// bound and the byte order; dds_stream_read then fills the generated C type), then converted as
// DdsTransport converts them (transport_detail::FromSample, transport/dds_wire.h) and checked as
// every received packet is (CheckPacket, transport/transport.h). The first byte picks the topic's
// type (bits 0-2) and swapped byte order (bit 4); the rest is the payload after the encapsulation
// header. A conversion may reject input only with a moslam::Error (the transport then counts and
// logs the sample); any other exception, a crash, a sanitizer report or a hang is a bug.
//
// XCDR1 only: the encoding the transport's writers send and its readers ask for (DdsTransport pins
// the data representation). This target found that Cyclone DDS 0.10.2, as Debian 12 packages it,
// accepts an XCDR2 sequence of 8-byte elements (double, unsigned long long) holding 4 bytes per
// element, then reads past the buffer (transport/README.md); that is Cyclone's, fixed upstream
// since, and out of this target's reach.
//
// With MOSLAM_FUZZ_WRITE_SEEDS=DIR set, the target writes one valid sample of each type into DIR
// (the seed corpus scripts/fuzz.sh starts from) and exits.
#include <dds/dds.h>
#include <dds/ddsi/ddsi_cdrstream.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/transport/dds_wire.h"
#include "moslam/transport/transport.h"

namespace {

using namespace moslam;
using namespace moslam::transport_detail;

void Require(bool ok) {
  if (!ok) __builtin_trap();
}

// Deserializes `bytes` as a sample of `desc` and hands it to the transport's conversion and check:
// what CheckPacket says of it as robot 0's (empty: accepted), or "dropped" when Cyclone's
// normalisation refuses the bytes, as on receipt, or "rejected" when the conversion does.
template <typename Sample, typename Sender>
std::string Take(const dds_topic_descriptor_t& desc, std::vector<std::uint8_t> bytes, bool bswap,
                 Sender sender_of) {
  Require(desc.m_size == sizeof(Sample));
  if (bytes.size() > std::numeric_limits<std::uint32_t>::max()) return "dropped";
  const auto size = static_cast<std::uint32_t>(bytes.size());
  bytes.reserve(bytes.size() + 1);  // never a null buffer (Cyclone never receives one)
  std::uint32_t offset = 0;
  char* data = reinterpret_cast<char*>(bytes.data());
  if (dds_stream_normalize_data(data, &offset, size, bswap, kXcdr1, desc.m_ops) == nullptr) {
    return "dropped";
  }
  dds_istream_t in;
  dds_istream_init(&in, size, data, kXcdr1);
  Sample sample;
  std::memset(&sample, 0, sizeof sample);
  dds_stream_read(&in, reinterpret_cast<char*>(&sample), desc.m_ops);
  std::string why = "rejected";
  try {
    const Packet packet = FromSample(sample);
    const int sender = sender_of(sample);
    CheckPacket(packet, sender, 1, {0, 1, 2, sender});
    why = CheckPacket(packet, sender, 0, {});
  } catch (const Error&) {
  }
  dds_sample_free(&sample, &desc, DDS_FREE_CONTENTS);
  return why;
}

std::string Decode(std::uint8_t mode, const std::vector<std::uint8_t>& bytes) {
  const bool bswap = (mode & 0x10) != 0;
  switch (mode % 8) {
    case 0:
      return Take<EstimatesSample>(moslam_msg_dds__DgsEstimates__desc, bytes, bswap,
                                   [](const EstimatesSample& s) { return s.sender; });
    case 1:
      return Take<StatusSample>(moslam_msg_dds__Status__desc, bytes, bswap,
                                [](const StatusSample& s) { return s.robot; });
    case 2:
      return Take<CoarseSample>(moslam_msg_dds__DgsCoarse__desc, bytes, bswap,
                                [](const CoarseSample& s) { return s.sender; });
    case 3:
      return Take<WeightsSample>(moslam_msg_dds__DgsWeights__desc, bytes, bswap,
                                 [](const WeightsSample& s) { return s.sender; });
    case 4:
      return Take<CovarianceSample>(moslam_msg_dds__DgsCovariance__desc, bytes, bswap,
                                    [](const CovarianceSample& s) { return s.sender; });
    case 5:
      return Take<ObjectListSample>(moslam_msg_dds__ObjectList__desc, bytes, bswap,
                                    [](const ObjectListSample& s) { return s.robot; });
    default:
      return Take<SharedSample>(moslam_msg_dds__SharedObjects__desc, bytes, bswap,
                                [](const SharedSample& s) { return s.sender; });
  }
}

// ---- seeds: one valid sample of each type, as XCDR1 in this machine's byte order --------------

// Writes `sample` as a seed, after checking that the harness takes it as the transport would
// (accepted by CheckPacket): a seed the transport rejects would start the fuzzer nowhere.
void WriteSeed(const std::string& dir, const std::string& name, std::uint8_t mode,
               const dds_topic_descriptor_t& desc, const void* sample) {
  dds_ostream_t os;
  dds_ostream_init(&os, 0, kXcdr1);
  dds_stream_write(&os, static_cast<const char*>(sample), desc.m_ops);
  const auto* begin = static_cast<const std::uint8_t*>(static_cast<const void*>(os.m_buffer));
  const std::vector<std::uint8_t> bytes(begin, begin + os.m_index);
  dds_ostream_fini(&os);
  const std::string why = Decode(mode, bytes);
  if (!why.empty()) {
    std::fprintf(stderr, "seed %s not accepted: %s\n", name.c_str(), why.c_str());
    std::exit(1);
  }
  std::ofstream out(dir + "/" + name, std::ios::binary);
  out.put(static_cast<char>(mode));
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  Require(static_cast<bool>(out));
}

void WriteSeeds(const std::string& dir) {
  std::vector<std::uint64_t> keys = {2, 4};
  std::vector<double> values;  // two identity rotations, row by row (stage 1)
  for (int k = 0; k < 2; ++k) values.insert(values.end(), {1, 0, 0, 0, 1, 0, 0, 0, 1});
  EstimatesSample e{};
  e.sender = 1;
  e.receiver = 0;
  e.round = 3;
  e.iteration = 2;
  e.stage = 1;
  e.initialised = true;
  Lend(keys, e.keys);
  Lend(values, e.values);
  WriteSeed(dir, "estimates", 0, moslam_msg_dds__DgsEstimates__desc, &e);

  std::vector<std::uint16_t> neighbours = {0, 2};
  std::vector<TeamPairSample> team(1);
  team[0].mine = 3;
  team[0].other = 5;
  team[0].other_robot = 2;
  team[0].mine_is_alpha = true;
  team[0].held = true;
  team[0].step = 7;
  team[0].orientation[3] = 1.0;
  StatusSample st{};
  st.robot = 1;
  st.solve = 8;
  st.incarnation = 1;
  st.state = 1;
  st.stage = 1;
  st.round = 2;
  Lend(neighbours, st.neighbours);
  Lend(team, st.team);
  WriteSeed(dir, "status", 1, moslam_msg_dds__Status__desc, &st);

  std::vector<double> center = {0.0, 1.0, 2.0}, diagonal(9, 1.0), residual(3, 0.5), blocks(9, 0.25);
  std::vector<std::uint16_t> block_robots = {2};
  CoarseSample c{};
  c.sender = 1;
  c.round = 4;
  c.stage = 1;
  c.kind = 1;
  c.iteration = 1;
  c.k = 3;
  c.ncols = 1;
  Lend(center, c.center);
  Lend(diagonal, c.diagonal);
  Lend(residual, c.residual);
  Lend(block_robots, c.block_robots);
  Lend(blocks, c.blocks);
  WriteSeed(dir, "coarse", 2, moslam_msg_dds__DgsCoarse__desc, &c);
  // A piece matrix of the refinement (kind 5): two pieces, one block between them.
  std::vector<std::uint32_t> piece_ids = {0, 1}, row_pieces = {0}, block_pieces = {1};
  std::vector<std::uint16_t> piece_robots = {1};
  std::vector<double> piece_values = {0, 0, 0, 1, 1, 1}, piece_block(36, 0.5);
  CoarseSample cp{};
  cp.sender = 1;
  cp.round = 5;
  cp.stage = 3;
  cp.kind = 5;
  cp.k = 6;
  cp.ncols = 1;
  Lend(center, cp.center);
  Lend(piece_ids, cp.piece_ids);
  Lend(piece_values, cp.piece_values);
  Lend(row_pieces, cp.block_row_pieces);
  Lend(piece_robots, cp.piece_block_robots);
  Lend(block_pieces, cp.block_pieces);
  Lend(piece_block, cp.piece_block_values);
  WriteSeed(dir, "coarse_pieces", 2, moslam_msg_dds__DgsCoarse__desc, &cp);

  std::vector<double> weights = {1.0, 0.0, 0.5};
  WeightsSample w{};
  w.sender = 1;
  w.receiver = 0;
  w.round = 9;
  w.gnc_round = 1;
  Lend(weights, w.weights);
  WriteSeed(dir, "weights", 3, moslam_msg_dds__DgsWeights__desc, &w);

  std::vector<double> upper;  // a 6 x 6 identity, row by row
  for (int i = 0; i < 6; ++i) {
    for (int j = i; j < 6; ++j) upper.push_back(i == j ? 1.0 : 0.0);
  }
  CovarianceSample cov{};
  cov.sender = 1;
  cov.receiver = 0;
  cov.round = 5;
  cov.dimension = 6;
  Lend(upper, cov.upper);
  WriteSeed(dir, "covariance", 4, moslam_msg_dds__DgsCovariance__desc, &cov);

  std::vector<ObjectPoseSample> objects(2);
  for (std::size_t i = 0; i < objects.size(); ++i) {
    objects[i].id = i + 1;
    std::strcpy(objects[i].label, i == 0 ? "chair" : "table");
    objects[i].position[0] = 1.5 * static_cast<double>(i);
    objects[i].orientation[3] = 1.0;
  }
  ObjectListSample list{};
  list.robot = 1;
  list.revision = 2;
  list.step = 30;
  Lend(objects, list.objects);
  WriteSeed(dir, "objects", 5, moslam_msg_dds__ObjectList__desc, &list);

  std::vector<PairSample> pairs(2), removed(1);
  pairs[0] = {1, 2};
  pairs[1] = {3, 4};
  removed[0] = {5, 6};
  SharedSample shared{};
  shared.sender = 1;
  shared.receiver = 0;
  shared.step = 30;
  Lend(pairs, shared.pairs);
  Lend(removed, shared.removed);
  WriteSeed(dir, "shared", 6, moslam_msg_dds__SharedObjects__desc, &shared);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  if (const char* dir = std::getenv("MOSLAM_FUZZ_WRITE_SEEDS")) {
    WriteSeeds(dir);
    std::exit(0);
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  Decode(data[0], std::vector<std::uint8_t>(data + 1, data + size));
  return 0;
}
