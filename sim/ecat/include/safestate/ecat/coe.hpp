// CoE (CANopen over EtherCAT, ETG.1000.6 5.6) of an emulated subdevice: its object
// dictionary and the SDO server behind its mailbox. SDO upload and download, expedited
// and normal (the whole value in one mailbox); segmented transfers, complete access, SDO
// information and emergencies are not offered and are answered with an abort code (or,
// for other services and protocols, a mailbox error reply) rather than silence.
// It stands in for the CoE firmware of a CiA 402 drive; nothing here is certified.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace safestate::ecat {

struct SubdeviceDesc;
enum class AlState : std::uint8_t;

namespace coe {

// SDO abort codes (ETG.1000.6 table 41) that the emulation answers with.
namespace abort_code {
inline constexpr std::uint32_t command = 0x05040001;          // command specifier not valid or unknown
inline constexpr std::uint32_t unsupported_access = 0x06010000;
inline constexpr std::uint32_t read_only = 0x06010002;        // write to a read-only object
inline constexpr std::uint32_t rxpdo_mapped = 0x06010006;     // mapped to the RxPDO: SDO download blocked in OP
inline constexpr std::uint32_t no_object = 0x06020000;        // object does not exist
inline constexpr std::uint32_t length = 0x06070010;           // length of the service parameter does not match
inline constexpr std::uint32_t no_subindex = 0x06090011;      // subindex does not exist
inline constexpr std::uint32_t value_range = 0x06090030;      // value range exceeded
inline constexpr std::uint32_t state = 0x08000022;            // not in the present device state
}  // namespace abort_code

// The standard text of an abort code (ETG.1000.6 table 41), or "unknown abort code".
const char* abort_text(std::uint32_t code) noexcept;

// Who may write an entry: nobody (RO), in any state with a mailbox (RW), or only in
// PRE-OP (the PDO assignment and the mode of operation: 0x08000022 in SAFE-OP and OP).
enum class Access : std::uint8_t { ro, rw, rw_preop };

struct Entry {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint8_t bytes = 0;  // 1, 2 or 4; 0 for a string (`text`, read-only)
  bool is_signed = false;
  Access access = Access::ro;
  std::int64_t min = 0;  // the range a download must respect (as the type reads it)
  std::int64_t max = 0;
  std::uint32_t value = 0;  // little-endian image of the value, `bytes` wide
  std::uint32_t reset = 0;  // power-on value
  const char* name = "";
  std::string text;  // VISIBLE_STRING entries
  // Mapped into a PDO: byte offset in the process RAM of that direction, -1 = none.
  int pdo_offset = -1;
  bool pdo_output = false;  // RxPDO (outputs) when mapped
  [[nodiscard]] std::int64_t as_int() const noexcept;
};

// The object dictionary of an emulated CiA 402 CSP drive (docs/ethercat.md lists it).
class Dictionary {
 public:
  Dictionary() = default;
  explicit Dictionary(const SubdeviceDesc& d);

  void reset() noexcept;  // power-on values (and no refusal cleared: that is a fault, not a value)
  [[nodiscard]] const Entry* find(std::uint16_t index, std::uint8_t sub) const noexcept;
  [[nodiscard]] bool has_index(std::uint16_t index) const noexcept;
  [[nodiscard]] const std::vector<Entry>& entries() const noexcept { return entries_; }
  [[nodiscard]] bool empty() const noexcept { return entries_.empty(); }
  // The value of an entry (0 if there is none), as its type reads it.
  [[nodiscard]] std::int64_t value(std::uint16_t index, std::uint8_t sub) const noexcept;

  // SDO services. `outputs` / `inputs` are the process RAM of the PDOs: a mapped object
  // reads from there (an output only in OP, where the process data owns it). Return 0 or
  // the abort code; nothing changes on an abort.
  std::uint32_t upload(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> outputs,
                       std::span<const std::uint8_t> inputs, AlState state, std::vector<std::uint8_t>& out) const;
  std::uint32_t download(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data, AlState state);

  // A fault for tests: every download to index:sub is refused with `code` (0 = none).
  void refuse(std::uint16_t index, std::uint8_t sub, std::uint32_t code) noexcept {
    refuse_index_ = index;
    refuse_sub_ = sub;
    refuse_code_ = code;
  }

 private:
  Entry* find_mut(std::uint16_t index, std::uint8_t sub) noexcept;
  std::vector<Entry> entries_;
  std::uint16_t refuse_index_ = 0;
  std::uint8_t refuse_sub_ = 0;
  std::uint32_t refuse_code_ = 0;
};

// One mailbox request (the bytes the master wrote into the receive mailbox, header
// included) -> the reply for the send mailbox (header included; empty = no reply).
// `counter` is the subdevice's own mailbox counter (1..7), advanced per reply.
std::vector<std::uint8_t> serve(Dictionary& od, std::span<const std::uint8_t> request,
                                std::span<const std::uint8_t> outputs, std::span<const std::uint8_t> inputs,
                                AlState state, std::size_t mailbox_bytes, std::uint8_t& counter);

}  // namespace coe
}  // namespace safestate::ecat
